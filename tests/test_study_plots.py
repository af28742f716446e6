"""The studies' figures are drawn from the JSON ``data`` alone (studies compute, plots apart):
each plot function on a small synthetic data dict, :func:`s2cl.studies.replot` from a saved JSON, and no
computation module importing matplotlib."""

from __future__ import annotations

import ast
import json
from pathlib import Path

import numpy as np
import pytest

from s2cl.errors import InputError
from s2cl.io.output import write_json
from s2cl.scene.scene import Scene
from s2cl.studies import STUDIES, replot
from s2cl.studies.common import load_study
from s2cl.studies.plots import PLOTS, plot_study

STUDIES_DIR = Path(__file__).resolve().parent.parent / "s2cl" / "studies"


def _cirrus() -> dict:
    wl = np.arange(1340.0, 1411.0)
    variants = [[c, w] for w in (10.0, 20.0, 30.0) for c in (1360.0, 1375.0, 1390.0)]
    spectrum = {str(wv): (5 - 3 * wv * np.exp(-((wl - 1378) / 15) ** 2)).tolist() for wv in (0.4, 1.0)}
    change = {case: {"0.4": -10.0 - j, "1.0": -25.0 - j} for j, case in
              enumerate(("as_6s", "single_removed", "spikes_removed"))}
    return {"wavelength_nm": wl.tolist(), "toa_radiance_1nm": spectrum,
            "toa_radiance_1nm_spikes_removed": {k: [x * 0.99 for x in v] for k, v in spectrum.items()},
            "band_radiance": {"0.4": np.linspace(3, 4, 9).tolist(), "1.0": np.linspace(1, 2, 9).tolist()},
            "variants": variants, "spikes": {"nodes_nm": [1362.5, 1397.5]},
            "change_pct": {"eq1": change, "gaussian": change}}


def _water_vapour() -> dict:
    shapes = [[[c, w], [b8, 20.0]] for b8 in (865.0, 870.0) for w in (10.0, 20.0) for c in (935.0, 940.0, 945.0)]
    rms = np.linspace(4, 9, len(shapes))
    return {"configurations": shapes, "nominal_configuration": 3,
            "table_configurations": [["ESA nominal", 3], ["B8a shift", 9], ["best #1", 0]],
            "rel_rms_pct": {"veg": rms.tolist(), "soil": (rms + 1).tolist(), "all": (rms + 0.5).tolist()},
            "winter": {"winter_lut": {"veg": 5.0, "soil": 6.0, "all": 5.5},
                       "summer_lut": {"veg": 5.5, "soil": 6.2, "all": 5.9},
                       "relative_increase_pct": {"veg": 10.0, "soil": 3.3, "all": 7.3}}}


def _water_vapour_1020() -> dict:
    variants = [[c, w] for w in (10.0, 20.0) for c in (1000.0, 1020.0, 1040.0)]
    classes = ("veg", "soil", "all")
    three = {c: [np.linspace(2 + i, 5 + i, len(variants)).tolist()] for i, c in enumerate(classes)}
    two = {c: [8.0 + i] for i, c in enumerate(classes)}
    scores = {"veg": 4.0, "soil": 12.0, "all": 8.0}
    return {"nominal_configuration": 0,
            "window": {"name": "N1020", "noise_band": "B9", "variants": variants, "headline": 4, "best": 0},
            "two_channel": {"rel_rms_pct": two, "rel_rms_pct_no_noise": {c: [v[0] - 1] for c, v in two.items()}},
            "three_channel": {"rel_rms_pct": three,
                              "rel_rms_pct_no_noise": {c: [[x - 1 for x in v[0]]] for c, v in three.items()}},
            "continuum_error_pct": {"two": {"veg": 3.5, "soil": 16.0}, "three": {"veg": 1.8, "soil": 8.0}},
            "winter": {t: {p: {c: v * f for c, v in scores.items()} for p, f in
                           (("midlatitude_winter", 1.0), ("midlatitude_summer", 1.1))} for t in ("two", "three")}}


def _aerosol() -> dict:
    return {"factor_errors": [-0.2, -0.1, 0.0, 0.1, 0.2], "rel_rms_pct_vs_factor_error": [30, 14, 3, 15, 31],
            "calibration_gain": 1.05, "rel_rms_pct_calibration": 12.0,
            "b1_variants": [[443.0, 20.0], [448.0, 20.0], [443.0, 30.0]], "rel_rms_pct_b1": [3.0, 3.2, 2.9]}


def _ozone() -> dict:
    wl = np.arange(400.0, 761.0)
    cases = [[250.0, 0.05], [250.0, 0.3], [400.0, 0.05], [400.0, 0.3]]
    key = [f"{o3:g}DU rho={rho:g}" for o3, rho in cases]
    return {"assumed_ozone_du": 330.0, "bands": ["B1", "B2", "B3"],
            "shapes": [[443.0, 20.0], [490.0, 65.0], [560.0, 35.0]], "cases": cases, "wavelength_nm": wl.tolist(),
            "band_error_pct": {k: [0.5 * s, 2 * s, 5 * s] for k, s in zip(key, (1, 0.5, -1, -0.5), strict=True)},
            "spectral_error_pct": {k: (s * 6 * np.exp(-((wl - 600) / 60) ** 2)).tolist()
                                   for k, s in zip(key, (1, 0.5, -1, -0.5), strict=True)}}


def _methane() -> dict:
    wl = np.arange(1450.0, 1801.0)
    return {"variants": [[1600.0, 80.0], [1610.0, 90.0], [1620.0, 100.0]],
            "band_transmittance": [0.997, 0.996, 0.995], "wavelength_nm": wl.tolist(),
            "methane_transmittance": (1 - 0.02 * np.exp(-((wl - 1666) / 10) ** 2)).tolist()}


def _stability() -> dict:
    shifts = np.linspace(-5.0, 5.0, 11)
    factors = np.array([0.8, 1.0, 1.2])

    def app(label: str, bands: list[str], nominal: float) -> dict:
        grow = {"shift": {b: (nominal * (1 + (k + 1) * 0.05 * shifts**2)).tolist() for k, b in enumerate(bands)},
                "width": {b: (nominal * (1 + 0.1 * np.abs(factors - 1))).tolist() for b in bands}}
        return {"label": label, "metric": "RMS of cab", "unit": "µg/cm²", "bands": bands, "nominal_error": nominal,
                "nominal_error_no_noise": nominal / 2, "error": grow,
                "error_no_noise": {k: {b: [x / 2 for x in v] for b, v in d.items()} for k, d in grow.items()}}

    return {"growth": 0.1, "shifts_nm": shifts.tolist(), "width_factors": factors.tolist(),
            "applications": [app("IGRM", ["B5", "B6"], 5.0), app("SAM", ["B12"], 36.0)]}


def _cellulose() -> dict:
    wl = np.arange(1950.0, 2301.0)
    variants = [[c, w] for c in (2080.0, 2100.0, 2120.0) for w in (10.0, 40.0)]
    rms = np.linspace(0.12, 0.2, len(variants))
    return {"variants": variants, "rms": rms.tolist(), "rms_noise_free": (rms - 0.01).tolist(), "best": 0,
            "co2_signal_fraction": [0.7, 0.8, 0.97, 0.96, 1.0, 0.99],
            "base": {"rms": 0.23, "rms_noise_free": 0.22}, "shoulders": [[2030.0, 20.0], [2210.0, 20.0]],
            "wavelength_nm": wl.tolist(), "co2_transmittance": (1 - 0.5 * np.exp(-((wl - 2060) / 15) ** 2)).tolist(),
            "water_transmittance": np.full(wl.size, 0.95).tolist(),
            "mean_reflectance": {"soil": np.full(wl.size, 0.4).tolist(), "npv": (0.3 - 0.03 * np.exp(
                -((wl - 2100) / 30) ** 2)).tolist()}}


def _instrument() -> dict:
    bands = ["B2", "B4", "B8", "B11"]

    def row(name: str, scale: float) -> dict:
        per_band = {b: scale * (k + 1) for k, b in enumerate(bands)}
        return {"instrument": name, "rms_effect": per_band, "rms_vs_truth": {b: 0.005 for b in bands}}
    return {"bands": bands, "product": "reflectance", "pixels": 57600,
            "rows": [row("ideal", 0.0), row("mtf", 0.01), row("coregistration", 0.004), row("smile", 0.001),
                     row("nonuniformity", 0.0005)]}


SYNTHETIC = {"cirrus": _cirrus, "water-vapour": _water_vapour, "water-vapour-1020": _water_vapour_1020,
             "aerosol": _aerosol, "ozone": _ozone,
             "methane": _methane, "stability": _stability, "cellulose": _cellulose,
             "instrument": _instrument}


def _pixels(path: Path) -> np.ndarray:
    import matplotlib.image as mpimg

    return mpimg.imread(path)


def test_every_study_has_a_figure() -> None:
    assert set(PLOTS) == set(STUDIES) == set(SYNTHETIC)


@pytest.mark.parametrize("kind", list(SYNTHETIC))
def test_figure_from_data_alone_and_replot(kind: str, tmp_path: Path) -> None:
    data = SYNTHETIC[kind]()
    direct = plot_study(kind, data, tmp_path / "direct.png")
    img = _pixels(direct)
    assert img.ndim == 3 and img.shape[0] > 100 and img.shape[1] > 100
    assert np.ptp(img[..., :3]) > 0.5       # something drawn, not a blank canvas
    js = write_json(tmp_path / f"{kind}.json", {"study": kind, "data": data})
    again = replot(js, tmp_path / "again.png")
    np.testing.assert_array_equal(_pixels(again), img)


def test_replot_of_a_real_study_matches_its_in_memory_data(tmp_path: Path) -> None:
    """Cirrus keeps some water columns as float keys in memory; JSON turns them into strings."""
    result = STUDIES["cirrus"](load_study(Scene.load("study-cirrus"), quick=True))
    direct = plot_study("cirrus", result.data, tmp_path / "direct.png")
    js = write_json(tmp_path / "cirrus.json", {"study": "cirrus", **result.to_json()})
    np.testing.assert_array_equal(_pixels(replot(js, tmp_path / "again.png")), _pixels(direct))


def test_replot_errors_are_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"study": "nope", "data": {}}))
    with pytest.raises(InputError, match="no figure for study 'nope'"):
        replot(bad, tmp_path / "x.png")
    bad.write_text(json.dumps({"study": "methane", "data": {"variants": []}}))
    with pytest.raises(InputError, match="the data lack 'band_transmittance'"):
        replot(bad, tmp_path / "x.png")
    bad.write_text("[1, 2]")
    with pytest.raises(InputError, match="not a study JSON"):
        replot(bad, tmp_path / "x.png")
    with pytest.raises(InputError, match="cannot read a study JSON"):
        replot(tmp_path / "missing.json", tmp_path / "x.png")
    assert not (tmp_path / "x.png").exists()


def test_computation_modules_import_no_matplotlib() -> None:
    drawing = {"matplotlib", "s2cl.io.plots", "s2cl.studies.plots"}
    for path in STUDIES_DIR.glob("*.py"):
        if path.name in ("plots.py", "__init__.py") or path.name.endswith("_plots.py"):
            continue
        names = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                names.add(node.module or "")
            elif isinstance(node, ast.Import):
                names.update(a.name for a in node.names)
        assert not {n for n in names if n.split(".")[0] == "matplotlib" or n in drawing}, path.name
