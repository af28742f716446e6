"""Property-based fuzzing (hypothesis) of what users feed s2cl: scenes (valid ones and mutations of
them: wrong types, out-of-range, NaN/inf, huge and negative numbers, odd paths, missing and extra
keys) through loading and everything ``s2cl sweep count`` checks, scene files as raw text, and the
CSV and ENVI library loaders (parameter rows and header fields included). Every outcome is success or an
``S2CLError`` whose message is one line; any other exception is a bug that a user would see as a traceback.
"""

from __future__ import annotations

import copy
import math
import tempfile
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from s2cl.errors import S2CLError
from s2cl.grid import SpectralGrid

FUZZ = settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
GRID = SpectralGrid(400.0, 1000.0, 10.0)

BASE: dict[str, Any] = {
    "scene": {"name": "fuzz"},
    "surface": {"library": "builtin:flat", "quantity": "reflectance", "copies": 3},
    "grid": {"start_nm": 400.0, "stop_nm": 2500.0, "step_nm": 1.0},
    "atmosphere": {"water_vapour": 1.5, "visibility_km": 23.0, "ozone": 330.0, "solar_zenith": 40.0},
    "correction": {"calibration_gain": 1.0},
    "effects": {"atmosphere": True, "correct": True, "seed": 1, "bits": 12},
    "analysis": {"kind": "igrm", "parameter": "rho", "igrm": {"max_iter": 20}},
    "sweep": {"bands": ["B4", "B5", "B6", "B7"], "step_nm": 5.0, "ranges": {
        "B4": {"left": 630.0, "right": 690.0, "min_width": 30.0, "max_width": 50.0},
        "B5": {"centres": [705.0, 710.0], "widths": [15.0, 20.0]},
        "B6": {"centre": 740.0, "width": 15.0},
        "B7": {"centre": 783.0, "width": 20.0}}},
    "compute": {"precision": "float32", "lanes": 8},
}

HOSTILE = st.one_of(
    st.integers(min_value=-(2**70), max_value=2**70),
    st.sampled_from([0, -1, 1, 2**31, 2**32, 2**63, 10**30]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([float("nan"), float("inf"), -float("inf"), 1e308, -1e308, 5e-324, 0.0, -0.0]),
    st.booleans(),
    st.text(max_size=40),
    st.sampled_from(["../../x", "/proc/self", "/dev/zero", "builtin:", "builtin:flat:2,nan", "x.csv", "",
                     "\x00", "B99", "b4", "table:missing.csv", "measured-S2C", "gvmi", "sam"]),
    st.lists(st.one_of(st.integers(-5, 3000), st.floats(), st.text(max_size=5)), max_size=5),
    st.dictionaries(st.text(max_size=8), st.integers(), max_size=3),
)


def _paths(d: Any, prefix: tuple = ()) -> list[tuple]:
    """Every key path of a nested dict (lists are leaves)."""
    out = []
    if isinstance(d, dict):
        for k, v in d.items():
            out.append((*prefix, k))
            out += _paths(v, (*prefix, k))
    return out


@st.composite
def mutated_scenes(draw: Any) -> dict[str, Any]:
    """The base scene with one to three mutations: a value replaced, a key deleted or an extra key added."""
    data = copy.deepcopy(BASE)
    for _ in range(draw(st.integers(1, 3))):
        paths = _paths(data)
        if not paths:
            break
        path = draw(st.sampled_from(paths))
        parent = data
        for k in path[:-1]:
            parent = parent[k]
        action = draw(st.sampled_from(["replace", "replace", "delete", "extra"]))
        if action == "replace":
            parent[path[-1]] = draw(HOSTILE)
        elif action == "delete":
            del parent[path[-1]]
        elif isinstance(parent.get(path[-1]), dict):
            parent[path[-1]][draw(st.text(min_size=1, max_size=10))] = draw(HOSTILE)
    return data


def assert_clean(err: S2CLError) -> None:
    text = str(err)
    assert text and "\n" not in text, text


def check_like_sweep_count(data: dict[str, Any], folder: Path) -> None:
    """What ``s2cl sweep count`` runs, minus the printing."""
    from s2cl.app.checks import check_sweep
    from s2cl.app.plan import count_table
    from s2cl.app.sweep_budget import sweep_resources
    from s2cl.io.budget import Budget
    from s2cl.scene.scene import Scene

    scene = Scene.from_dict(data, path=folder / "fuzz.toml")
    checked = check_sweep(scene)
    count_table(checked)
    sweep_resources(checked, budget=Budget(2**31, "the fuzz test's limit"))


@FUZZ
@given(data=mutated_scenes())
def test_mutated_scenes_load_and_count_or_fail_in_one_line(data: dict[str, Any]) -> None:
    with tempfile.TemporaryDirectory() as folder:
        try:
            check_like_sweep_count(data, Path(folder))
        except S2CLError as err:
            assert_clean(err)


def test_the_base_scene_is_valid(tmp_path) -> None:
    check_like_sweep_count(copy.deepcopy(BASE), tmp_path)


TOML_PIECES = st.sampled_from(["[scene]\n", 'name = "x"\n', "[surface]\n", 'library = "builtin:flat"\n',
                               "copies = 1e400\n", "[", "]", "= ", "\"", "'''", "nan", "inf", "[[a]]\n", "\x00",
                               "\ufeff", "x = 1\n", "x = 1\n", "[effects]\n", "bits = -1\n", "{", "}"])


@FUZZ
@given(text=st.one_of(st.text(max_size=300), st.lists(TOML_PIECES, max_size=30).map("".join)),
       raw=st.binary(max_size=200))
def test_scene_files_of_any_content_load_or_fail_in_one_line(text: str, raw: bytes) -> None:
    from s2cl.scene.scene import Scene

    with tempfile.TemporaryDirectory() as folder:
        for content in (text.encode("utf-8", "surrogatepass"), raw):
            path = Path(folder) / "s.toml"
            path.write_bytes(content)
            try:
                Scene.load(path)
            except S2CLError as err:
                assert_clean(err)


CELL = st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr), st.integers(-10**6, 10**6).map(str),
                 st.text(max_size=6), st.sampled_from(["", " ", "nan", "1e999", "0.5", "-0", "1,5"]))


@st.composite
def csv_texts(draw: Any) -> str:
    """Mostly well-formed libraries (wavelengths over the grid) with a few hostile cells, headers and rows."""
    if draw(st.integers(0, 9)) == 0:
        return draw(st.text(max_size=400))
    rare = st.integers(0, 15)
    first = "wavelength_nm" if draw(rare) else draw(st.sampled_from(["wavelength_um", "wavelength", "lambda", ""]))
    names = [f"s{i}" for i in range(draw(st.integers(1, 3)))]
    if not draw(rare):
        names = draw(st.lists(st.text(max_size=8), max_size=3))
    step = 10.0 if draw(st.integers(0, 5)) else draw(st.sampled_from([5.0, 30.0, 0.0, -10.0, 0.001]))
    rows = []
    for i in range(draw(st.integers(2, 70))):
        w = repr(380.0 + i * step) if draw(st.integers(0, 40)) else draw(CELL)
        cells = [draw(CELL) if draw(st.integers(0, 40)) == 0 else "0.3" for _ in names]
        row = [w, *cells]
        if not draw(st.integers(0, 60)):
            row = row[: draw(st.integers(1, len(row)))] + draw(st.lists(CELL, max_size=2))
        rows.append(",".join(row))
    if not draw(st.integers(0, 3)):  # a parameter row, mostly right after the header
        name = draw(st.sampled_from(["param:cab", "param:Cab", "PARAM:lai", "param:", "param:c-b", "param:cab"]))
        at = 0 if draw(st.integers(0, 5)) else draw(st.integers(0, len(rows)))
        rows.insert(at, ",".join([name, *(draw(CELL) if draw(st.integers(0, 8)) == 0 else "1.5" for _ in names)]))
    return "\n".join([",".join([first, *names]), *rows]) + "\n"


@FUZZ
@given(text=csv_texts(), quantity=st.sampled_from(["reflectance", "radiance"]))
def test_csv_libraries_load_or_fail_in_one_line(text: str, quantity: str) -> None:
    from s2cl.libraries.files import load_csv_library

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "lib.csv"
        path.write_bytes(text.encode("utf-8", "surrogatepass"))
        try:
            lib = load_csv_library(path, GRID, quantity=quantity)
        except S2CLError as err:
            assert_clean(err)
        else:
            assert lib.spectra.shape[1] == GRID.size and all(math.isfinite(v) for v in lib.spectra.ravel())
            assert all(v.shape == (lib.size,) and all(map(math.isfinite, v)) for v in lib.params.values())


HEADER_VALUE = st.one_of(st.integers(-3, 5), st.sampled_from(["2", "1", "0", "-1", "x", "99999999", "{1, 2}",
                                                              "{400, 700, 1000}", "{}", "nan"]), st.text(max_size=8))


ENVI_WAVELENGTHS = list(range(400, 1001, 10))
VALID_HEADER = {"samples": str(len(ENVI_WAVELENGTHS)), "lines": "2", "bands": "1", "header offset": "0",
                "file type": "ENVI Spectral Library", "data type": "4", "interleave": "bsq", "byte order": "0",
                "wavelength units": "Nanometers", "wavelength": "{" + ", ".join(map(str, ENVI_WAVELENGTHS)) + "}",
                "spectra names": "{a, b}"}
HOSTILE_HEADER = {
    "samples": HEADER_VALUE, "lines": HEADER_VALUE, "bands": st.sampled_from(["1", "x", "2"]),
    "header offset": st.sampled_from(["0", "-4", "8", "x"]),
    "file type": st.sampled_from(["ENVI Standard", ""]), "data type": st.sampled_from(["5", "12", "99", "x"]),
    "interleave": st.sampled_from(["bil", "zzz"]), "byte order": st.sampled_from(["1", "7"]),
    "wavelength units": st.sampled_from(["Micrometers", "parsecs", ""]),
    "wavelength": st.sampled_from(["{0.4, 0.7, 1.0}", "{1000, 400, 700}", "{}", "{400, x, 1000}", "{400, 1000}"]),
    "spectra names": st.sampled_from(["{a}", "{}", "{a, a}", "{a, b, c}"]),
    "reflectance scale factor": st.sampled_from(["1", "0", "-1", "x", "1e400", "100"]),
    "data ignore value": st.sampled_from(["-9999", "x", "nan", "0"]),
    "bbl": st.sampled_from(["{1, 1, 1}", "{1, 0}", "{x}", "{1, 0, 1}"]),
    "s2cl parameter cab": st.sampled_from(["{40, 50}", "{40}", "{40, x}", "{inf, 1}", "3", "{1, 2, 3}", "{}"]),
    "s2cl parameter c-b": st.just("{1, 2}"),
    "s2cl parameters": st.just("{1, 2}"),
}


@st.composite
def envi_files(draw: Any) -> tuple[str, bytes]:
    """A valid two-spectrum library (float32, 61 wavelengths) with some header fields made hostile, dropped
    or added, and its data replaced by random bytes now and then; or a header of random text."""
    import numpy as np

    if draw(st.integers(0, 9)) == 0:
        return draw(st.text(max_size=200)), draw(st.binary(max_size=96))
    fields = dict(VALID_HEADER)
    for key in draw(st.lists(st.sampled_from(sorted(HOSTILE_HEADER)), max_size=3, unique=True)):
        fields[key] = draw(HOSTILE_HEADER[key])
    for key in draw(st.lists(st.sampled_from(sorted(fields)), max_size=1)):
        del fields[key]
    values = np.full(2 * len(ENVI_WAVELENGTHS), 0.3, dtype="<f4")
    for i in draw(st.lists(st.integers(0, values.size - 1), max_size=2)):
        values[i] = draw(st.floats(width=32, allow_nan=True, allow_infinity=True))
    data = values.tobytes() if draw(st.integers(0, 4)) else draw(st.binary(max_size=600))
    return "ENVI\n" + "".join(f"{k} = {v}\n" for k, v in fields.items()), data


@FUZZ
@given(files=envi_files())
def test_envi_libraries_load_or_fail_in_one_line(files: tuple[str, bytes]) -> None:
    pytest.importorskip("spectral")
    from s2cl.libraries.files import load_envi_library

    header, data = files
    with tempfile.TemporaryDirectory() as folder:
        (Path(folder) / "lib.hdr").write_bytes(header.encode("utf-8", "surrogatepass"))
        (Path(folder) / "lib.sli").write_bytes(data)
        try:
            lib = load_envi_library(Path(folder) / "lib.sli", GRID)
        except S2CLError as err:
            assert_clean(err)
        else:
            assert lib.spectra.shape[1] == GRID.size
