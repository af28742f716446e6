"""Per-spectrum parameters in user libraries: CSV ``param:NAME`` rows, ENVI ``s2cl parameter NAME``
header fields and s2cl ``.npz`` files carry Lib1's Cab into ``s2cl optimise``, ``simulate`` and ``sweep count``
exactly as the builtin library does; hostile parameter rows, header fields and archives are one-line errors
naming the file and the key (exit code 2 through the command line)."""

from __future__ import annotations

import json
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from sweep_fixtures import SMALL_SWEEP_TOML

from s2cl.cli.main import main
from s2cl.errors import InputError
from s2cl.grid import DEFAULT_GRID, SpectralGrid
from s2cl.libraries.files import load_csv_library, load_envi_library
from s2cl.libraries.npz import load_npz_library, write_library_file
from s2cl.libraries.registry import load_library

envi = pytest.importorskip("spectral.io.envi")

SMALL = SpectralGrid(400.0, 1000.0, 1.0)
FORMATS = ("lib1.csv", "lib1.sli", "lib1.npz")


# {{{ writers


def write_csv(path: Path, w: np.ndarray, spectra: np.ndarray, names: list[str], params: dict[str, np.ndarray]) -> Path:
    """A CSV library with one ``param:NAME`` row per parameter; numbers written with repr(): exact."""
    lines = ["wavelength_nm," + ",".join(names)]
    lines += [f"param:{k}," + ",".join(repr(float(x)) for x in v) for k, v in params.items()]
    lines += [",".join([repr(float(wj)), *(repr(float(x)) for x in spectra[:, j])]) for j, wj in enumerate(w)]
    path.write_text("\n".join(lines) + "\n")
    return path


def write_envi(base: Path, w: np.ndarray, spectra: np.ndarray, names: list[str], params: dict[str, np.ndarray]) -> Path:
    """An ENVI library (float64 data, written by SPy) with ``s2cl parameter NAME = {...}`` header fields."""
    hdr = {"wavelength": [repr(float(x)) for x in w], "spectra names": names, "wavelength units": "Nanometers"}
    hdr.update({f"s2cl parameter {k}": [repr(float(x)) for x in v] for k, v in params.items()})
    envi.SpectralLibrary(np.asarray(spectra, dtype=np.float64), hdr, None).save(str(base))
    return base.with_suffix(".sli")


def write_npz(path: Path, w: np.ndarray, spectra: np.ndarray, names: list[str], params: dict[str, np.ndarray],
              **metadata) -> Path:
    return write_library_file(path, wavelength_nm=w, spectra=spectra, names=names, groups=["user"] * len(names),
                              params=params, metadata=metadata or None, dtype=np.float64)


@pytest.fixture(scope="module")
def lib1():
    return load_library("builtin:lib1", DEFAULT_GRID)


@pytest.fixture(scope="module")
def folder(tmp_path_factory, lib1) -> Path:
    """Lib1 on the default grid as CSV, ENVI and .npz, each with cab, lai and ewt."""
    root = tmp_path_factory.mktemp("params")
    w, names = DEFAULT_GRID.wavelengths, [f"s{i}" for i in range(lib1.size)]
    write_csv(root / "lib1.csv", w, lib1.spectra, names, lib1.params)
    write_envi(root / "lib1", w, lib1.spectra, names, lib1.params)
    write_npz(root / "lib1.npz", w, lib1.spectra, names, lib1.params)
    return root


def scene(root: Path, library: str, name: str, copies: int = 2) -> Path:
    """The small IGRM sweep (Lib1's 6 configurations) over ``library``."""
    path = root / f"{name}.toml"
    text = SMALL_SWEEP_TOML.format(copies=copies).replace('"builtin:lib1"', f'"{library}"')
    path.write_text(text.replace('name = "small"', f'name = "{name}"'))
    return path


def run_main(args: list[str]) -> int:
    """``s2cl ARGS`` in this process: its exit code."""
    try:
        main(args)
    except SystemExit as done:
        return done.code if isinstance(done.code, int) else 1
    return 0


def one_line(code: int, err: str, *parts: str) -> str:
    lines = err.splitlines()
    assert code == 2, (code, err)
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in err, err
    for part in parts:
        assert part in lines[0], (part, lines[0])
    return lines[0]


# }}}
# {{{ round trips


@pytest.mark.parametrize("name", FORMATS)
def test_each_format_carries_the_spectra_and_parameters_exactly(folder: Path, lib1, name: str) -> None:
    lib = load_library(name, DEFAULT_GRID, base_dir=folder)
    np.testing.assert_array_equal(lib.spectra, lib1.spectra)
    assert sorted(lib.params) == ["cab", "ewt", "lai"]
    for key, values in lib1.params.items():
        np.testing.assert_array_equal(lib.params[key], values)
        assert lib.params[key].dtype == np.float64


@pytest.fixture(scope="module")
def optimised(folder: Path) -> dict[str, object]:
    """results.parquet of ``s2cl optimise`` on the builtin library and on each file."""
    out = {}
    for i, library in enumerate(("builtin:lib1", *FORMATS)):
        path = scene(folder, library, f"opt{i}")
        assert run_main(["optimise", "-q", str(path), "-o", str(folder / f"out{i}")]) == 0
        out[library] = pq.read_table(folder / f"out{i}" / "results.parquet")
    return out


@pytest.mark.parametrize("name", FORMATS)
def test_optimise_on_each_format_equals_the_builtin_library(optimised: dict, name: str) -> None:
    ref, table = optimised["builtin:lib1"], optimised[name]
    assert table.num_rows == ref.num_rows == 6
    assert np.isfinite(ref.column("rms").to_numpy()).all()
    assert table.equals(ref), name  # every column of every configuration, bit for bit


def test_the_comparison_sees_another_parameter(folder: Path, lib1, optimised: dict) -> None:
    """The same spectra with Cab shuffled (not reversed: 105 - Cab is affine in Cab, and the regression absorbs
    it): the metrics differ, so the equality above can fail."""
    params = dict(lib1.params, cab=np.random.default_rng(16).permutation(lib1.params["cab"]))
    names = [f"s{i}" for i in range(lib1.size)]
    write_csv(folder / "reversed.csv", DEFAULT_GRID.wavelengths, lib1.spectra, names, params)
    assert run_main(["optimise", "-q", str(scene(folder, "reversed.csv", "reversed")), "-o",
                     str(folder / "out-reversed")]) == 0
    table = pq.read_table(folder / "out-reversed" / "results.parquet")
    assert not np.allclose(table.column("rms").to_numpy(), optimised["builtin:lib1"].column("rms").to_numpy())


def test_simulate_and_sweep_count_use_the_files_parameter(folder: Path, capsys) -> None:
    rms = {}
    for library, name in (("builtin:lib1", "simb"), ("lib1.csv", "simc")):
        assert run_main(["simulate", "-q", str(scene(folder, library, name)), "-o", str(folder / name)]) == 0
        rms[library] = json.loads((folder / name / "simulation.json").read_text())["analysis"]["rms"]
    assert rms["lib1.csv"] == rms["builtin:lib1"] and 0 < rms["lib1.csv"] < 30
    capsys.readouterr()
    assert run_main(["sweep", "count", str(scene(folder, "lib1.npz", "count"))]) == 0
    assert "configurations: 6" in capsys.readouterr().out


def test_a_parameter_the_library_lacks_is_named_with_those_it_has(folder: Path, lib1, capsys) -> None:
    names = [f"s{i}" for i in range(lib1.size)]
    write_csv(folder / "lai.csv", DEFAULT_GRID.wavelengths, lib1.spectra, names, {"lai": lib1.params["lai"]})
    for command in (["simulate"], ["optimise"], ["sweep", "count"]):
        code = run_main([*command, str(scene(folder, "lai.csv", "lai"))])
        one_line(code, capsys.readouterr().err, "lai.toml: analysis.parameter: library has no parameter 'cab'; "
                 "it has lai")


# }}}
# {{{ CSV


def _small(n: int = 3) -> tuple[np.ndarray, np.ndarray, list[str]]:
    w = SMALL.wavelengths
    x = (w - 400.0) / 600.0
    return w, np.array([0.2 + 0.1 * k + 0.1 * x for k in range(n)]), [f"s{k}" for k in range(n)]


def test_csv_parameter_rows_with_comments_semicolons_and_case(tmp_path: Path) -> None:
    w, spectra, names = _small()
    path = write_csv(tmp_path / "p.csv", w, spectra, names, {"Cab": np.array([45.2, 30.1, 1e-3])})
    text = path.read_text().replace(",", ";").replace("param:Cab", "# a comment\nPARAM: Cab ")
    path.write_text(text)
    lib = load_csv_library(path, SMALL)
    np.testing.assert_array_equal(lib.params["Cab"], [45.2, 30.1, 1e-3])
    np.testing.assert_array_equal(lib.spectra, spectra)
    assert load_csv_library(write_csv(tmp_path / "none.csv", w, spectra, names, {}), SMALL).params == {}


def _csv_with(tmp_path: Path, rows: list[str], after: int = 0) -> Path:
    """A 3-spectrum CSV with ``rows`` inserted after wavelength row ``after`` (0: right after the header)."""
    w, spectra, names = _small()
    path = write_csv(tmp_path / "bad.csv", w, spectra, names, {})
    lines = path.read_text().splitlines()
    lines[1 + after : 1 + after] = rows
    path.write_text("\n".join(lines) + "\n")
    return path


BAD_CSV = {
    "duplicate": (["param:cab,1,2,3", "param:cab,1,2,3"], 0,
                  r"bad\.csv: param:cab: is given twice \(line 2 and line 3\)"),
    "duplicate but for case": (["param:cab,1,2,3", "param:CAB,1,2,3"], 0, r"param:CAB: is given twice"),
    "bad name": (["param:c-ab,1,2,3"], 0, r"bad\.csv: param:c-ab: parameter name 'c-ab' must be 1-32 letters"),
    "no name": (["param:,1,2,3"], 0, r"parameter name '' must be"),
    "digit first": (["param:1cab,1,2,3"], 0, r"param:1cab: parameter name '1cab' must be"),
    "too long": ([f"param:{'a' * 33},1,2,3"], 0, r"must be 1-32 letters, digits or _"),
    "hostile name": (["param:\x1b[2J../x,1,2,3"], 0, r"bad\.csv: param:'\?\[2J\.\./x': parameter name"),
    "too few values": (["param:cab,1,2"], 0, r"bad\.csv: param:cab: line 2: 2 values for 3 spectra"),
    "too many values": (["param:cab,1,2,3,4"], 0, r"line 2: 4 values for 3 spectra"),
    "empty value": (["param:cab,1,,3"], 0, r"param:cab: line 2: no value for spectrum 's1'"),
    "text value": (["param:cab,1,x,3"], 0, r"param:cab: line 2: 'x', not a number, for spectrum 's1'"),
    "grouped digits": (["param:cab,1,2_0,3"], 0, r"line 2: '2_0', not a number"),
    "inf value": (["param:cab,1,2,inf"], 0, r"param:cab: line 2: value inf for spectrum 's2' is not finite"),
    "nan value": (["param:cab,nan,2,3"], 0, r"line 2: value nan for spectrum 's0' is not finite"),
    "after the data": (["param:cab,1,2,3"], 5, r"param:cab: line 7: parameter rows come before the first wavelength "
                                                r"row \(line 2\)"),
}


@pytest.mark.parametrize("case", list(BAD_CSV), ids=list(BAD_CSV))
def test_csv_bad_parameter_rows_name_file_line_and_parameter(tmp_path: Path, case: str) -> None:
    rows, after, pattern = BAD_CSV[case]
    with pytest.raises(InputError, match=pattern) as info:
        load_csv_library(_csv_with(tmp_path, rows, after), SMALL)
    assert "\n" not in str(info.value)


def test_csv_with_parameter_rows_but_one_wavelength_row(tmp_path: Path) -> None:
    path = tmp_path / "short.csv"
    path.write_text("wavelength_nm,a\nparam:cab,1\nparam:lai,2\n400,0.1\n")
    with pytest.raises(InputError, match=r"short\.csv: needs a header row and at least 2 wavelength rows"):
        load_csv_library(path, SMALL)


# }}}
# {{{ ENVI


def _envi(tmp_path: Path, **params) -> Path:
    w, spectra, names = _small()
    return write_envi(tmp_path / "lib", w, spectra, names, {k: np.asarray(v, float) for k, v in params.items()})


def test_envi_header_parameters(tmp_path: Path) -> None:
    sli = _envi(tmp_path, cab=[45.2, 30.1, 5.0], lai=[1, 2, 3])
    lib = load_envi_library(sli, SMALL)
    np.testing.assert_array_equal(lib.params["cab"], [45.2, 30.1, 5.0])
    np.testing.assert_array_equal(lib.params["lai"], [1.0, 2.0, 3.0])
    (tmp_path / "none").mkdir()
    assert load_envi_library(_envi(tmp_path / "none"), SMALL).params == {}


def _edit_header(sli: Path, old: str, new: str) -> Path:
    hdr = sli.with_suffix(".hdr")
    text = hdr.read_text()
    assert old in text, text[-300:]
    hdr.write_text(text.replace(old, new))
    return sli


BAD_ENVI = {
    "count": ("s2cl parameter cab = { 1.0 , 2.0 , 3.0 }", "s2cl parameter cab = {1, 2}",
              r"lib\.hdr: s2cl parameter cab: lists 2 values for lines = 3"),
    "scalar": ("s2cl parameter cab = { 1.0 , 2.0 , 3.0 }", "s2cl parameter cab = 1",
               r"s2cl parameter cab: must be a list in braces"),
    "text": ("s2cl parameter cab = { 1.0 , 2.0 , 3.0 }", "s2cl parameter cab = {1, x, 3}",
             r"s2cl parameter cab: value 2 \('x'\) for spectrum 's1' is not a number"),
    "empty": ("s2cl parameter cab = { 1.0 , 2.0 , 3.0 }", "s2cl parameter cab = {1, , 3}",
              r"value 2 \(''\) for spectrum 's1' is not a number"),
    "inf": ("s2cl parameter cab = { 1.0 , 2.0 , 3.0 }", "s2cl parameter cab = {1, 2, -inf}",
            r"s2cl parameter cab: value -inf for spectrum 's2' is not finite"),
    "duplicate": ("s2cl parameter cab = { 1.0 , 2.0 , 3.0 }",
                  "s2cl parameter cab = {1, 2, 3}\ns2cl parameter CAB = {\n 4, 5, 6}",
                  r"lib\.hdr: s2cl parameter cab: is given twice \(line \d+ and line \d+\)"),
    "bad name": ("s2cl parameter cab = { 1.0 , 2.0 , 3.0 }", "s2cl parameter c-ab = {1, 2, 3}",
                 r"s2cl parameter c-ab: parameter name 'c-ab' must be 1-32"),
    "no name": ("s2cl parameter cab = { 1.0 , 2.0 , 3.0 }", "s2cl parameter = {1, 2, 3}",
                r"lib\.hdr: 's2cl parameter': line \d+: unknown s2cl header field"),
    "unknown": ("s2cl parameter cab = { 1.0 , 2.0 , 3.0 }", "s2cl parameters cab = {1, 2, 3}",
                r"unknown s2cl header field; s2cl reads 's2cl parameter NAME = \{v1, v2, \.\.\.\}'"),
}


@pytest.mark.parametrize("case", list(BAD_ENVI), ids=list(BAD_ENVI))
def test_envi_bad_parameter_fields_name_header_and_key(tmp_path: Path, case: str) -> None:
    old, new, pattern = BAD_ENVI[case]
    sli = _edit_header(_envi(tmp_path, cab=[1, 2, 3]), old, new)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # SPy's note on the upper-case key (CAB) is not printed
        with pytest.raises(InputError, match=pattern) as info:
            load_envi_library(sli, SMALL)
    assert "\n" not in str(info.value)


# }}}
# {{{ .npz


def test_npz_parameters_and_metadata(tmp_path: Path) -> None:
    w, spectra, names = _small()
    path = write_npz(tmp_path / "l.npz", w, spectra, names, {"cab": np.array([1.0, 2.0, 3.0])},
                     source="my PROSAIL runs")
    lib = load_npz_library(path, SMALL)
    np.testing.assert_array_equal(lib.params["cab"], [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(lib.spectra, spectra)
    assert lib.quantity == "reflectance" and lib.source == "my PROSAIL runs"


def _npz_members(tmp_path: Path, **arrays) -> Path:
    """A valid small library file with some arrays replaced (``None``: removed)."""
    w, spectra, names = _small()
    path = write_npz(tmp_path / "x.npz", w, spectra, names, {"cab": np.array([1.0, 2.0, 3.0])})
    with np.load(path, allow_pickle=False) as z:
        data = {k: z[k] for k in z.files}
    for key, value in arrays.items():
        if value is None:
            data.pop(key)
        else:
            data[key] = value
    np.savez(path, **data)
    return path


def _meta(**changes) -> np.ndarray:
    meta = {"format": "s2cl-spectral-library", "format_version": 1, "quantity": "reflectance"}
    meta.update(changes)
    return np.asarray(json.dumps(meta))


BAD_NPZ = {
    "foreign": (lambda p: np.savez(p, a=np.zeros(3)), r"x\.npz: library file lacks the arrays wavelength_nm"),
    "not a zip": (lambda p: p.write_bytes(b"\x93NUMPY garbage" * 10), r"x\.npz: not a readable s2cl library file"),
    "truncated": (lambda p: p.write_bytes(p.read_bytes()[:300]), r"x\.npz: not a readable s2cl library file"),
    "random bytes after PK": (lambda p: p.write_bytes(b"PK\x03\x04" + bytes(range(256))),
                              r"not a readable s2cl library file"),
    "a member that is not an array": (lambda p: _append(p, "evil.npy", b"hello"), r"not a readable s2cl library file"),
    "pickled names": (lambda p: np.savez(p, **dict(_arrays(p), names=np.array(["a", 1, None], dtype=object))),
                      r"x\.npz: names: holds an array of Python objects"),
    "wrong parameter count": (lambda p: np.savez(p, **dict(_arrays(p), param__cab=np.ones(2))),
                              r"x\.npz: param__cab: declares float64 of shape \(2,\); an s2cl library file holds "
                              r"numbers of shape \(3,\)"),
    "text parameter": (lambda p: np.savez(p, **dict(_arrays(p), param__cab=np.array(["a", "b", "c"]))),
                       r"param__cab: declares <U1"),
    "nan parameter": (lambda p: np.savez(p, **dict(_arrays(p), param__cab=np.array([1, np.nan, 3]))),
                      r"x\.npz: param__cab: value nan for spectrum 's1' is not finite"),
    "bad parameter name": (lambda p: np.savez(p, **dict(_arrays(p), **{"param__c-ab": np.ones(3)})),
                           r"param__c-ab: parameter name 'c-ab' must be"),
    "names differ by case": (lambda p: np.savez(p, **dict(_arrays(p), param__CAB=np.ones(3))),
                             r"param__CAB: is given twice \(array param__cab and array param__CAB\)"),
    "spectra shape": (lambda p: np.savez(p, **dict(_arrays(p), spectra=np.ones((3, 5)))),
                      r"x\.npz: spectra: declares float64 of shape \(3, 5\); an s2cl library file holds floats of "
                      r"shape \(spectra, 601\)"),
    "metadata not json": (lambda p: np.savez(p, **dict(_arrays(p), metadata=np.asarray("{nope"))),
                          r"x\.npz: metadata: is not JSON"),
    "metadata a list": (lambda p: np.savez(p, **dict(_arrays(p), metadata=np.asarray("[1]"))),
                        r"metadata: must be a JSON object"),
    "other format": (lambda p: np.savez(p, **dict(_arrays(p), metadata=_meta(format="lut"))),
                     r"x\.npz: library file format 'lut' v1 is not 's2cl-spectral-library' v1"),
    "unknown quantity": (lambda p: np.savez(p, **dict(_arrays(p), metadata=_meta(quantity="dn"))),
                         r"metadata: quantity 'dn' is not one of reflectance, radiance"),
    "percent": (lambda p: np.savez(p, **dict(_arrays(p), spectra=_arrays(p)["spectra"] * 100)),
                r"x\.npz: s0: value 20 at 400 nm is outside the reflectance range"),
    "unsorted wavelengths": (lambda p: np.savez(p, **dict(_arrays(p), wavelength_nm=_arrays(p)["wavelength_nm"][::-1])),
                             r"x\.npz: wavelength_nm: must be strictly increasing"),
}


def _arrays(path: Path) -> dict[str, np.ndarray]:
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def _append(path: Path, name: str, content: bytes) -> None:
    with zipfile.ZipFile(path, "a") as zf:
        zf.writestr(name, content)


@pytest.mark.parametrize("case", list(BAD_NPZ), ids=list(BAD_NPZ))
def test_npz_bad_files_are_one_line_naming_file_and_array(tmp_path: Path, case: str) -> None:
    spoil, pattern = BAD_NPZ[case]
    path = _npz_members(tmp_path)
    spoil(path)
    with pytest.raises(InputError, match=pattern) as info:
        load_npz_library(path, SMALL)
    assert "\n" not in str(info.value)


def test_npz_that_declares_too_much_is_refused_before_loading(tmp_path: Path, monkeypatch) -> None:
    from s2cl.libraries import npz

    path = _npz_members(tmp_path)
    monkeypatch.setattr(npz, "MAX_LIBRARY_BYTES", 1000)
    with pytest.raises(InputError, match=r"x\.npz: its arrays declare [\d,]+ bytes \(at most 1,000\)"):
        load_npz_library(path, SMALL)


# }}}
# {{{ through the command line


@pytest.mark.parametrize(("name", "write", "parts"), [
    ("dup.csv", lambda p: p.write_text("wavelength_nm,a\nparam:cab,1\nparam:cab,2\n400,0.1\n2500,0.1\n"),
     ("dup.csv: param:cab: is given twice",)),
    ("count.sli", lambda p: _edit_header(_envi(p.parent, cab=[1, 2, 3]), "{ 1.0 , 2.0 , 3.0 }", "{1, 2}"),
     ("lib.hdr: s2cl parameter cab: lists 2 values for lines = 3",)),
    ("corrupt.npz", lambda p: p.write_bytes(b"PK\x03\x04 not really a zip"),
     ("corrupt.npz: not a readable s2cl library file",)),
    ("missing.npz", lambda p: None, ("scene.toml: surface.library: spectral library file", "missing.npz not found")),
])
@pytest.mark.parametrize("command", [["simulate"], ["optimise"], ["sweep", "count"]])
def test_bad_parameter_files_through_the_cli_are_one_line(tmp_path: Path, monkeypatch, capsys, name: str, write,
                                                          parts: tuple[str, ...], command: list[str]) -> None:
    monkeypatch.chdir(tmp_path)
    write(tmp_path / name)
    library = "lib.sli" if name == "count.sli" else name
    path = scene(tmp_path, library, "scene")
    code = run_main([*command, str(path)])
    one_line(code, capsys.readouterr().err, *parts)
    assert not (tmp_path / "s2cl-out").exists()


# }}}
