"""Flat targets and user spectral libraries (CSV, ENVI .sli/.hdr through SPy): round trips and every bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from s2cl.errors import InputError
from s2cl.grid import DEFAULT_GRID, SpectralGrid
from s2cl.libraries.files import load_csv_library, load_envi_library
from s2cl.libraries.library import flat_targets

envi = pytest.importorskip("spectral.io.envi")

SMALL = SpectralGrid(400.0, 1000.0, 1.0)


def _smooth_spectra(w_nm: np.ndarray, n: int = 3) -> np.ndarray:
    """Distinct smooth reflectance spectra in (0, 1) on ``w_nm``."""
    x = (w_nm - 400.0) / 2100.0
    return np.array([0.15 + 0.1 * k + 0.2 * x + 0.05 * np.sin(6.0 * (k + 1) * x) for k in range(n)])


def _write_csv(path: Path, header: str, w: np.ndarray, spectra: np.ndarray, *, sep: str = ",") -> Path:
    lines = [header]
    for j, wj in enumerate(w):
        lines.append(sep.join([repr(float(wj))] + [repr(float(v)) for v in spectra[:, j]]))
    path.write_text("\n".join(lines) + "\n")
    return path


# {{{ flat targets


def test_flat_targets_default_values_and_metadata():
    lib = flat_targets(DEFAULT_GRID)
    assert lib.spectra.shape == (2, DEFAULT_GRID.size)
    np.testing.assert_array_equal(lib.spectra[0], 0.1)
    np.testing.assert_array_equal(lib.spectra[1], 0.2)
    np.testing.assert_array_equal(lib.params["rho"], [0.1, 0.2])
    assert lib.groups == ["flat", "flat"]
    assert lib.names == ["flat 0.1", "flat 0.2"]


def test_flat_targets_any_values_including_bounds():
    lib = flat_targets(SMALL, [0.0, 0.05, 1.0])
    assert lib.size == 3
    np.testing.assert_array_equal(lib.spectra.min(axis=1), [0.0, 0.05, 1.0])
    np.testing.assert_array_equal(lib.spectra.max(axis=1), [0.0, 0.05, 1.0])


@pytest.mark.parametrize("values", [[-0.1], [1.2], [np.nan], [np.inf], []])
def test_flat_targets_reject_bad_values(values):
    with pytest.raises(InputError, match=r"flat\.values"):
        flat_targets(SMALL, values)


# }}}
# {{{ CSV


def test_csv_round_trip_on_grid_is_exact(tmp_path):
    w = SMALL.wavelengths
    spectra = _smooth_spectra(w)
    path = _write_csv(tmp_path / "lib.csv", "wavelength_nm,a,b,c", w, spectra)
    lib = load_csv_library(path, SMALL)
    assert lib.names == ["a", "b", "c"]
    assert lib.source == str(path)
    np.testing.assert_array_equal(lib.spectra, spectra)


def test_csv_micrometres_coarse_steps_interpolated_like_numpy(tmp_path):
    w_nm = np.arange(395.0, 1006.0, 5.0)
    spectra = _smooth_spectra(w_nm, 2)
    path = _write_csv(tmp_path / "um.csv", "wavelength_um,x,y", w_nm / 1000.0, spectra)
    lib = load_csv_library(path, SMALL)
    for i in range(2):
        expected = np.interp(SMALL.wavelengths, w_nm, spectra[i])  # float64 oracle
        np.testing.assert_allclose(lib.spectra[i], expected, rtol=0, atol=1e-12)


@pytest.mark.parametrize(("scale_to", "unit"), [(1.0, None), (1000.0, None), (1.0, "um"), (1000.0, "nm")])
def test_csv_plain_wavelength_column_detects_or_takes_declared_unit(tmp_path, scale_to, unit):
    w_nm = SMALL.wavelengths
    factor = 1.0 if scale_to == 1000.0 else 1e-3
    path = _write_csv(tmp_path / "w.csv", "wavelength,s", w_nm * factor, _smooth_spectra(w_nm, 1))
    lib = load_csv_library(path, SMALL, wavelength_unit=unit)
    np.testing.assert_allclose(lib.spectra[0], _smooth_spectra(w_nm, 1)[0], atol=1e-12)


def test_csv_semicolons_comments_and_quoted_names(tmp_path):
    w = SMALL.wavelengths
    spectra = _smooth_spectra(w, 2)
    path = tmp_path / "semi.csv"
    _write_csv(path, 'wavelength_nm;"grass; dry";soil', w, spectra, sep=";")
    path.write_text("# measured 2024\n" + path.read_text())
    lib = load_csv_library(path, SMALL)
    assert lib.names == ["grass; dry", "soil"]


def test_csv_percent_needs_scale(tmp_path):
    w = SMALL.wavelengths
    path = _write_csv(tmp_path / "pct.csv", "wavelength_nm,p", w, 100.0 * _smooth_spectra(w, 1))
    with pytest.raises(InputError, match=r"pct\.csv: p: .*reflectance range"):
        load_csv_library(path, SMALL)
    lib = load_csv_library(path, SMALL, scale=0.01)
    np.testing.assert_allclose(lib.spectra[0], _smooth_spectra(w, 1)[0], atol=1e-12)


def _bad_csv(tmp_path: Path, mutate) -> Path:
    w = SMALL.wavelengths
    header, rows = "wavelength_nm,a,b", [[repr(float(x)), "0.2", "0.3"] for x in w]
    header, rows = mutate(header, rows)
    path = tmp_path / "bad.csv"
    path.write_text("\n".join([header] + [",".join(r) for r in rows]) + "\n")
    return path


def _set(rows, i, col, value):
    rows[i][col] = value
    return rows


BAD_CSV = {
    "nan cell": (lambda h, r: (h, _set(r, 100, 2, "nan")), r"bad\.csv: b: holds a non-finite value \(nan\) at 500 nm"),
    "empty cell": (lambda h, r: (h, _set(r, 7, 1, "")), r"bad\.csv: a: holds a non-finite value \(nan\) at 407 nm"),
    "inf cell": (lambda h, r: (h, _set(r, 3, 1, "inf")), r"bad\.csv: a: holds a non-finite value \(inf\)"),
    "text cell": (lambda h, r: (h, _set(r, 3, 2, "n/a")), r"bad\.csv: b: line 5: 'n/a' is not a number"),
    "not increasing": (
        lambda h, r: (h, _set(r, 10, 0, "405.0")),
        r"bad\.csv: wavelength_nm: must be strictly increasing; position 10 \(405 nm\) follows 409 nm",
    ),
    "duplicate wavelength": (lambda h, r: (h, _set(r, 10, 0, "409.0")), r"strictly increasing; position 10"),
    "nan wavelength": (
        lambda h, r: (h, _set(r, 2, 0, "nan")),
        r"wavelength_nm: holds a non-finite value at position 2",
    ),
    "ragged row": (lambda h, r: (h, [*r[:5], r[5][:2], *r[6:]]), r"bad\.csv: line 7 has 2 fields, the header has 3"),
    "bad first column": (lambda h, r: ("lambda,a,b", r), r"first column must be named wavelength_nm"),
    "duplicate names": (lambda h, r: ("wavelength_nm,a,a", r), r"unique"),
    "no spectra": (lambda h, r: ("wavelength_nm", [[x[0]] for x in r]), r"no spectrum column"),
    "too short": (lambda h, r: (h, r[:1]), r"at least 2 wavelength rows"),
    "does not cover": (lambda h, r: (h, r[50:]), r"bad\.csv: spectra cover 450–1000 nm but the grid needs 400–1000 nm"),
    "gap": (lambda h, r: (h, r[:200] + r[260:]), r"no data between 599 and 660 nm \(61 nm gap > 25 nm\)"),
    "negative": (lambda h, r: (h, _set(r, 4, 1, "-0.5")), r"bad\.csv: a: value -0.5 at 404 nm is outside"),
}


@pytest.mark.parametrize("case", list(BAD_CSV), ids=list(BAD_CSV))
def test_csv_bad_input_names_file_and_column(tmp_path, case):
    mutate, pattern = BAD_CSV[case]
    with pytest.raises(InputError, match=pattern):
        load_csv_library(_bad_csv(tmp_path, mutate), SMALL)


def test_csv_gap_allowed_when_asked(tmp_path):
    path = _bad_csv(tmp_path, lambda h, r: (h, r[:200] + r[260:]))
    lib = load_csv_library(path, SMALL, max_gap_nm=100.0)
    np.testing.assert_allclose(lib.spectra[1], 0.3)


def test_csv_missing_file_and_binary(tmp_path):
    with pytest.raises(InputError, match=r"nope\.csv: spectral library file not found"):
        load_csv_library(tmp_path / "nope.csv", SMALL)
    binary = tmp_path / "bin.csv"
    binary.write_bytes(bytes(range(256)) * 4)
    with pytest.raises(InputError, match=r"bin\.csv"):
        load_csv_library(binary, SMALL)


def test_csv_unit_conflict(tmp_path):
    path = _bad_csv(tmp_path, lambda h, r: (h, r))
    with pytest.raises(InputError, match="column name says nm"):
        load_csv_library(path, SMALL, wavelength_unit="um")
    with pytest.raises(InputError, match="is not nm or µm"):
        load_csv_library(_bad_csv(tmp_path, lambda h, r: ("wavelength,a,b", r)), SMALL, wavelength_unit="cm")


# }}}
# {{{ ENVI


def _write_sli(base: Path, w: np.ndarray, spectra: np.ndarray, names: list[str], **header) -> Path:
    """Write an ENVI spectral library with SPy itself (``base``.hdr + ``base``.sli)."""
    hdr = {"wavelength": [float(x) for x in w], "spectra names": names, "wavelength units": "Nanometers"}
    hdr.update(header)
    envi.SpectralLibrary(np.asarray(spectra, dtype=np.float32), hdr, None).save(str(base))
    return base.with_suffix(".sli")


def test_envi_round_trip_written_by_spy(tmp_path):
    w = SMALL.wavelengths
    spectra = _smooth_spectra(w)
    sli = _write_sli(tmp_path / "lib", w, spectra, ["grass", "soil", "rock"])
    for path in (sli, tmp_path / "lib.hdr"):
        lib = load_envi_library(path, SMALL)
        assert lib.names == ["grass", "soil", "rock"]
        np.testing.assert_allclose(lib.spectra, spectra, rtol=0, atol=3e-8)  # float32 storage in .sli


def test_envi_micrometres_scale_factor_and_bad_bands(tmp_path):
    w_nm = np.arange(390.0, 1011.0, 2.0)
    spectra = _smooth_spectra(w_nm, 2)
    bbl = np.ones(w_nm.size, dtype=int)
    bbl[[40, 41]] = 0  # 470, 472 nm flagged bad: dropped, the 6 nm gap is bridged
    stored = 10000.0 * spectra
    stored[:, bbl == 0] = -9999.0
    sli = _write_sli(
        tmp_path / "um",
        w_nm / 1000.0,
        stored,
        ["a", "b"],
        **{"wavelength units": "Micrometers", "reflectance scale factor": 10000, "bbl": list(bbl)},
    )
    lib = load_envi_library(sli, SMALL)
    good = bbl == 1
    for i in range(2):
        expected = np.interp(SMALL.wavelengths, w_nm[good], spectra[i, good])
        np.testing.assert_allclose(lib.spectra[i], expected, atol=1e-7)


def test_envi_sli_hdr_naming(tmp_path):
    w = SMALL.wavelengths
    _write_sli(tmp_path / "x", w, _smooth_spectra(w, 1), ["only"])
    (tmp_path / "x.hdr").rename(tmp_path / "x.sli.hdr")
    assert load_envi_library(tmp_path / "x.sli", SMALL).names == ["only"]
    assert load_envi_library(tmp_path / "x.sli.hdr", SMALL).names == ["only"]


def test_envi_missing_files(tmp_path):
    w = SMALL.wavelengths
    sli = _write_sli(tmp_path / "lib", w, _smooth_spectra(w, 1), ["a"])
    with pytest.raises(InputError, match=r"nothing\.sli: ENVI library data file \(\.sli\) not found"):
        load_envi_library(tmp_path / "nothing.sli", SMALL)
    (tmp_path / "lib.hdr").unlink()
    with pytest.raises(InputError, match=r"lib\.sli: ENVI header not found \(looked for lib\.sli\.hdr, lib\.hdr"):
        load_envi_library(sli, SMALL)
    with pytest.raises(InputError, match=r"lib\.hdr: ENVI header not found"):
        load_envi_library(tmp_path / "lib.hdr", SMALL)


def test_envi_malformed_header_and_data(tmp_path):
    w = SMALL.wavelengths
    sli = _write_sli(tmp_path / "lib", w, _smooth_spectra(w, 2), ["a", "b"])
    hdr = tmp_path / "lib.hdr"
    good_header = hdr.read_text()
    hdr.write_text("not an envi header\n")
    with pytest.raises(InputError, match=r"lib\.hdr: not a readable ENVI spectral library"):
        load_envi_library(sli, SMALL)
    hdr.write_text(good_header.replace("ENVI Spectral Library", "ENVI Standard"))
    with pytest.raises(InputError, match=r"lib\.hdr: file type: "):
        load_envi_library(sli, SMALL)
    no_wavelength = "\n".join(ln for ln in good_header.splitlines() if not ln.startswith("wavelength ="))
    hdr.write_text(no_wavelength + "\n")
    with pytest.raises(InputError, match=r"lib\.hdr: wavelength: header has no 'wavelength' list"):
        load_envi_library(sli, SMALL)
    hdr.write_text(good_header)
    sli.write_bytes(sli.read_bytes()[:1000])  # truncated data: the header key that no longer holds is named
    with pytest.raises(InputError, match=r"lib\.hdr: lines: .* need 4,808 bytes; lib\.sli holds 1,000"):
        load_envi_library(sli, SMALL)


def test_envi_nan_and_coverage_errors(tmp_path):
    w = SMALL.wavelengths
    spectra = _smooth_spectra(w, 2)
    spectra[1, 300] = np.nan
    sli = _write_sli(tmp_path / "nan", w, spectra, ["ok", "broken"])
    with pytest.raises(InputError, match=r"nan\.sli: broken: holds a non-finite value \(nan\) at 700 nm"):
        load_envi_library(sli, SMALL)
    sli = _write_sli(tmp_path / "short", w, _smooth_spectra(w, 1), ["a"])
    with pytest.raises(InputError, match=r"short\.sli: spectra cover 400–1000 nm but the grid needs 400–2500 nm"):
        load_envi_library(sli, DEFAULT_GRID)


# }}}


def test_envi_data_ignore_value_is_missing_data(tmp_path):
    w = SMALL.wavelengths
    spectra = _smooth_spectra(w, 2)
    spectra[0, 250] = -1.23e34  # USGS splib 'deleted channel' marker
    sli = _write_sli(tmp_path / "ign", w, spectra, ["a", "b"])
    hdr = tmp_path / "ign.hdr"  # SPy always writes 'data ignore value = NaN' for libraries: set it by hand
    text = hdr.read_text()
    assert "data ignore value = NaN" in text
    hdr.write_text(text.replace("data ignore value = NaN", "data ignore value = -1.23e34"))
    with pytest.raises(InputError, match=r"ign\.sli: a: holds a non-finite value \(nan\) at 650 nm"):
        load_envi_library(sli, SMALL)
    lib = load_envi_library(sli, SpectralGrid(700.0, 1000.0, 1.0))  # the missing value is outside this grid
    np.testing.assert_allclose(lib.spectra[0], spectra[0, 300:], atol=3e-8)


def test_envi_header_values_that_are_not_numbers(tmp_path):
    w = SMALL.wavelengths
    sli = _write_sli(tmp_path / "h", w, _smooth_spectra(w, 1), ["a"], **{"reflectance scale factor": "lots"})
    with pytest.raises(InputError, match=r"h\.hdr: reflectance scale factor: must be a number, got 'lots'"):
        load_envi_library(sli, SMALL)


def test_missing_values_outside_the_grid_are_harmless(tmp_path):
    w = np.arange(350.0, 1051.0, 1.0)
    spectra = _smooth_spectra(w, 1)
    spectra[0, :30] = np.nan  # 350-379 nm: no data, as in many ASD files
    spectra[0, -5:] = np.nan
    path = _write_csv(tmp_path / "edges.csv", "wavelength_nm,a", w, spectra)
    lib = load_csv_library(path, SMALL)
    np.testing.assert_array_equal(lib.spectra[0], spectra[0, 50:651])
    with pytest.raises(InputError, match=r"edges\.csv: a: holds a non-finite value \(nan\) at 1046 nm"):
        load_csv_library(path, SpectralGrid(400.0, 1050.0, 1.0))
