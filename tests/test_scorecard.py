"""``s2cl scorecard``: band roles by wavelength, the sensor catalogue, cells scored as a sweep's reference row, n/a
cells, the outputs and the errors."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
from sweep_fixtures import SMALL_SWEEP_TOML
from test_cli_errors import run_main

import s2cl
from s2cl.app.scorecard import AppInfo, Cell, Scorecard, scorecard
from s2cl.app.scorecard_report import heatmap, write_scorecard
from s2cl.errors import DependencyError
from s2cl.sensor import catalogue
from s2cl.sensor.catalogue import CatalogueSensor, catalogue_sensor
from s2cl.sensor.roles import DEFAULT_TOLERANCE_NM, map_roles, nearest_band
from s2cl.sensor.sensor import Band, Sensor

#: the issue's Landsat Next VSWIR table, typed again here (band: GSD m / centre nm / width nm)
LANDSAT_NEXT = [("Violet", 60, 412, 20), ("Coastal", 20, 443, 20), ("Blue", 10, 490, 65), ("Green", 10, 560, 35),
                ("Yellow", 20, 600, 30), ("Orange", 20, 620, 20), ("Red1", 20, 650, 20), ("Red2", 10, 665, 30),
                ("RedEdge1", 20, 705, 15), ("RedEdge2", 20, 740, 15), ("NIR broad", 10, 842, 115),
                ("NIR1", 20, 865, 20), ("Water vapour", 60, 945, 20), ("Liquid water", 20, 985, 20),
                ("Snow/Ice1", 20, 1035, 20), ("Snow/Ice2", 20, 1090, 20), ("Cirrus", 60, 1375, 30),
                ("SWIR1", 10, 1610, 90), ("SWIR2a", 20, 2038, 25), ("SWIR2b", 20, 2108, 40), ("SWIR2c", 20, 2211, 40)]


def _band(name: str, centre: float, width: float = 20.0) -> Band:
    return Band(name, centre, width, 1.0, 50.0, 300.0, ((50.0, 100.0),), 20.0)


def _sensor(*bands: tuple[str, float]) -> Sensor:
    return Sensor("hand", tuple(_band(n, c) for n, c in bands))


def test_roles_map_to_the_nearest_band_within_the_tolerance() -> None:
    s = _sensor(("R1", 650), ("R2", 665), ("E1", 700), ("E2", 720))
    assert DEFAULT_TOLERANCE_NM == 15.0
    assert nearest_band(s, 705) == "E1"  # 5 nm from 700, 15 from 720
    assert nearest_band(s, 783) is None  # 63 nm from the nearest
    assert nearest_band(s, 657.5) == "R1"  # a tie: the band listed first
    assert nearest_band(s, 685) == "E1"  # 15 nm from 700 (20 from 665): exactly the tolerance counts
    assert nearest_band(s, 685, tolerance_nm=14.99) is None
    assert nearest_band(s, 735.01) is None  # 15.01 nm from 720
    m = map_roles({"B4": 665.0, "B5": 705.0, "B7": 783.0}, s)
    assert m.bands == {"B4": "R2", "B5": "E1"}
    assert m.missing == "no band near 783 nm (B7, within 15 nm)"
    assert map_roles({"B4": 665.0, "B5": 705.0}, s).missing is None


def test_roles_by_name_first_and_one_band_per_role() -> None:
    s = _sensor(("B4", 675), ("B5", 725), ("N", 855))
    assert map_roles({"B5": 705.0}, s).missing == "no band near 705 nm (B5, within 15 nm)"
    assert map_roles({"B5": 705.0}, s, by_name=True).bands == {"B5": "B5"}  # a design's B5, wherever it moved
    both = map_roles({"B8": 842.0, "B8a": 865.0}, s)
    assert both.bands == {"B8": "N", "B8a": "N"}
    assert both.missing == "B8 and B8a would both be band N (855 nm)"


def test_landsat_next_table_as_the_issue_gives_it() -> None:
    ln = catalogue_sensor("landsat-next")
    assert ln.sensor is not None and ln.unavailable is None
    bands = ln.sensor.bands
    assert len(bands) == len(LANDSAT_NEXT) == 21
    for i, (band, (label, gsd, centre, width)) in enumerate(zip(bands, LANDSAT_NEXT, strict=True), start=1):
        assert band.name == f"B{i}"
        assert (band.gsd_m, band.centre_nm, band.fwhm_nm) == (gsd, centre, width), label
        assert band.tabulated is None  # eq. 1
    assert ln.labels["B9"] == "Red Edge 1" and ln.labels["B21"] == "SWIR 2c"
    assert "landsat.gsfc.nasa.gov" in ln.source and "eq. 1" in ln.srf and "stand-in" in ln.radiometry
    assert nearest_band(ln.sensor, 783.0) is None  # no 783 nm band: IGRM's fourth band and S2REP are n/a


def test_stand_in_radiometry_is_the_nearest_table1_band_scaled_by_width() -> None:
    oli2 = catalogue_sensor("L9").sensor
    assert oli2 is not None
    red = oli2.band("B4")  # 655/30: Table 1's B4 (665/30): Lmin 3.31, Lref 108, Lmax 484.1, SNR 142 at Lref
    assert (red.lmin, red.lref, red.lmax, red.centre_nm, red.fwhm_nm, red.gsd_m) == (3.31, 108.0, 484.1, 655, 30, 30)
    cirrus = oli2.band("B9")  # 1370/20: Table 1's B10 (1375/30, SNR 50 at Lref = 6, shot noise only)
    a, b = cirrus.noise_coefficients()
    snr = 6.0 / math.sqrt(a + b * 6.0)
    assert snr == pytest.approx(50.0 * math.sqrt(20.0 / 30.0), rel=1e-9)


def test_unknown_sensor_names_the_known_ones() -> None:
    from s2cl.errors import InputError

    with pytest.raises(InputError, match="known: sentinel2, S2A, S2B, OLI, OLI-2, landsat-next"):
        catalogue_sensor("sentinel3")
    assert catalogue_sensor("landsat8").name == "OLI" and catalogue_sensor("s2a").name == "S2A"


def test_measured_srfs_unavailable_are_na_or_eq1_not_an_error(monkeypatch, tmp_path) -> None:
    def no_py6s(platform: str, band: str):
        raise DependencyError('measured SRFs come from Py6S: pip install "s2cl[sixs]"')

    monkeypatch.setattr(catalogue, "measured_sentinel2_srf", no_py6s)
    monkeypatch.setattr(catalogue, "measured_oli_srf", lambda band: no_py6s("OLI", band))
    s2b = catalogue_sensor("S2B")
    assert s2b.sensor is None and "Py6S" in (s2b.unavailable or "")
    oli = catalogue_sensor("OLI")  # falls back to eq. 1 at the published centres and widths, and says so
    assert oli.sensor is not None and all(b.tabulated is None for b in oli.sensor.bands)
    assert "eq. 1" in oli.srf and "not installed" in oli.srf
    card = scorecard(_scene(tmp_path), ["sentinel2", "S2B"])
    cell = card.cell("cab", "S2B")
    assert cell.score is None and "Py6S" in (cell.na or "") and card.relative(cell) is None


def test_measured_srfs_enter_the_cell(tmp_path) -> None:
    pytest.importorskip("Py6S")
    s2a = catalogue_sensor("S2A")
    assert s2a.sensor is not None and all(b.tabulated is not None and b.own_response for b in s2a.sensor.bands)
    card = scorecard(_scene(tmp_path), ["sentinel2", "S2A"])
    model, measured = card.cell("cab", "sentinel2"), card.cell("cab", "S2A")
    assert measured.na is None and measured.score != model.score  # same centres and widths, other responses
    assert measured.row["n_valid"] == model.row["n_valid"]  # the same pixels


def _scene(tmp_path: Path, b4_centres: str = "665, 675, 685", copies: int = 2) -> Path:
    text = SMALL_SWEEP_TOML.format(copies=copies).replace("centres = [665, 675, 685]", f"centres = [{b4_centres}]")
    path = tmp_path / "small.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("b4_centres", ["665, 675, 685", "675, 685"], ids=["own-design-swept", "own-design-not-swept"])
def test_own_sensor_cell_is_the_optimise_reference_row(tmp_path, b4_centres) -> None:
    from s2cl.app.optimise import optimise

    scene = _scene(tmp_path, b4_centres)
    result = optimise(scene, tmp_path / "out")
    reference, best = result.summary["reference"], result.summary["best"]
    card = scorecard(scene, ["sentinel2", f"results:{tmp_path / 'out'}"])
    own = card.cell("cab", "sentinel2")
    assert own.na is None and own.score == reference["rms"]
    kept = [k for k in reference if k not in ("bands", "config", "configurations_better", "within_noise")]
    assert len(kept) > 10
    assert {k: own.row[k] for k in kept} == {k: reference[k] for k in kept}  # bit for bit, every column
    design = card.cell("cab", f"best:{'out'}")
    assert design.na is None and design.score == best["rms"]  # the sweep's #1 design scores as the sweep did
    assert {r: (b["centre_nm"], b["width_nm"]) for r, b in design.bands.items()} == {
        b: tuple(cw) for b, cw in best["bands"].items()}


def test_cli_scorecard_na_cells_and_outputs(tmp_path, capsys) -> None:
    scene = _scene(tmp_path)
    code, _out, err = run_main(["scorecard", str(scene), "-s", "sentinel2", "-s", "landsat-next", "-s", "OLI-2",
                               "-o", str(tmp_path / "card")], capsys)
    assert code == 0, err
    assert "scorecard: cab on landsat-next: n/a (no band near 783 nm (B7, within 15 nm))" in err
    assert "scorecard: cab on OLI-2: n/a (no band near 705 nm (B5, within 15 nm))" in err
    rows = list(csv.DictReader((tmp_path / "card" / "scorecard.csv").open()))
    assert [(r["sensor"], r["n/a"] == "") for r in rows] == [("sentinel2", True), ("landsat-next", False),
                                                             ("OLI-2", False)]
    assert float(rows[0]["relative_to_best"]) == 1.0 and rows[1]["score"] == ""
    assert rows[1]["bands"] == "B4=B8 665/30 B5=B9 705/15 B6=B10 740/15"
    record = json.loads((tmp_path / "card" / "scorecard.json").read_text())
    assert record["tolerance_nm"] == 15.0 and record["applications"][0]["metric"] == "rms"
    assert record["cells"][1]["n/a"].startswith("no band near 783 nm")
    assert [s["name"] for s in record["sensors"]] == ["sentinel2", "landsat-next", "OLI-2"]
    assert (tmp_path / "card" / "scorecard.png").stat().st_size > 1000


def _hand_card() -> Scorecard:
    sensors = [CatalogueSensor(n, n, "", "", "", None) for n in ("s1", "s2", "s3")]
    apps = [AppInfo("cab", "igrm", "cab", "rms", "µg/cm²"), AppInfo("min", "sam", None, "omission_error_pct", "%")]
    cells = [Cell("cab", "s1", 4.0, None), Cell("cab", "s2", 5.0, None), Cell("cab", "s3", None, "no band near 783 nm"),
             Cell("min", "s1", 30.0, None), Cell("min", "s2", None, "unavailable"), Cell("min", "s3", 24.0, None)]
    return Scorecard("hand", 15.0, apps, sensors, cells)


def test_heatmap_cells_are_scores_over_the_best_sensor(tmp_path) -> None:
    card = _hand_card()
    fig = heatmap(card)
    drawn = fig.axes[0].images[0].get_array()
    expected = np.ma.masked_invalid([[1.0, 1.25, np.nan], [30.0 / 24.0, np.nan, 1.0]])
    assert np.array_equal(drawn.mask, expected.mask)
    assert np.allclose(drawn.compressed(), expected.compressed(), rtol=0, atol=1e-15)
    texts = [t.get_text() for t in fig.axes[0].texts]
    assert sum(t.startswith("n/a") for t in texts) == 2 and "1.250\n(5)" in texts
    written = write_scorecard(card, tmp_path)
    assert [p.name for p in written] == ["scorecard.csv", "scorecard.json", "scorecard.png"]
    rows = list(csv.DictReader((tmp_path / "scorecard.csv").open()))
    assert [r["relative_to_best"] for r in rows] == ["1.0", "1.25", "", "1.25", "", "1.0"]


@pytest.mark.parametrize("args, says", [
    (["-s", "sentinel3"], "--sensor: unknown sensor 'sentinel3'; known: sentinel2, S2A, S2B, OLI, OLI-2, "
                          "landsat-next"),
    (["-s", "missing.csv"], "missing.csv"),
    (["-s", "bad.csv"], "missing columns"),
    (["-s", "results:nothing"], "no summary.json in nothing"),
])
def test_cli_errors_are_one_line(tmp_path, monkeypatch, capsys, args, says) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "bad.csv").write_text("band,centre_nm\nB1,443\n")
    (tmp_path / "nothing").mkdir()
    code, _out, err = run_main(["scorecard", "default", "-q", "-o", "card", *args], capsys)
    assert code == 2 and err.count("\n") == 1 and err.startswith("error: ") and says in err, err
    assert not (tmp_path / "card").exists()


MULTI_TOML = """
[scene]
name = "multi-small"
[surface]
library = "builtin:lib1"
quantity = "reflectance"
copies = 2
[effects]
atmosphere = true
correct = true
[[application]]
name = "chlorophyll"
[application.analysis]
kind = "igrm"
parameter = "cab"
[[application]]
name = "lai"
[application.analysis]
kind = "ndvi"
parameter = "lai"
[sweep]
bands = ["B4", "B5", "B6", "B8"]
[sweep.ranges]
B4 = { centres = [665, 675], widths = [30] }
B5 = { centre = 705, width = 15 }
B6 = { centre = 740, width = 15 }
B8 = { centre = 842, width = 115 }
"""


def test_application_scenes_score_each_application_on_the_bands_it_reads(tmp_path) -> None:
    multi = tmp_path / "multi.toml"
    multi.write_text(MULTI_TOML)
    card = scorecard(multi, ["sentinel2", "OLI-2"])
    assert [a.name for a in card.applications] == ["chlorophyll", "lai"]
    lai = card.cell("lai", "sentinel2")
    assert list(lai.bands) == ["B8", "B4"]  # the index reads NIR and red only (its roles in order)
    assert card.cell("lai", "OLI-2").na == "no band near 842 nm (B8, within 15 nm)"  # not "near 705 nm"
    # IGRM without analysis.bands reads its family's B4-B7, as the multi-application sweep gives it (not the [sweep]
    # bands), and its own-sensor cell is the sweep's own-bands score for it, bit for bit
    assert list(card.cell("chlorophyll", "sentinel2").bands) == ["B4", "B5", "B6", "B7"]
    swept = s2cl.optimise(multi, tmp_path / "swept")
    refs = {a["name"]: a["reference"] for a in swept.summary["applications"]}
    assert card.cell("chlorophyll", "sentinel2").score == refs["chlorophyll"]
    assert lai.score == refs["lai"]
    # the same index alone, on a sweep of its own two bands: the same score, bit for bit
    alone = tmp_path / "ndvi.toml"
    alone.write_text(MULTI_TOML.split("[[application]]")[0] + '[analysis]\nkind = "ndvi"\nparameter = "lai"\n'
                     '[sweep]\nbands = ["B4", "B8"]\n[sweep.ranges]\nB4 = { centre = 665, width = 30 }\n'
                     'B8 = { centre = 842, width = 115 }\n')
    assert scorecard(alone, ["sentinel2"]).cell("lai", "sentinel2").score == lai.score


def test_a_balanced_design_without_a_finite_relative_sum_is_named_not_a_crash() -> None:
    from s2cl.app.scorecard import summary_design

    summary = {"pareto": {"front": {"order": "relative sum",
                                    "designs": [{"bands": {"B5": [710.0, 15.0]}, "relative_sum": None}]}}}
    bands, what = summary_design(summary, "balanced", Path("summary.json"))
    assert bands == {"B5": [710.0, 15.0]} and what.endswith("relative sum, n/a)")


def test_own_response_keeps_a_measured_srf_only_at_the_bands_own_shape() -> None:
    from s2cl.sensor.srf import TabulatedResponse

    table = TabulatedResponse(np.array([650.0, 665.0, 680.0]), np.array([0.0, 1.0, 0.0]), origin="hand")
    band = Band("B4", 665.0, 30.0, 1.0, 50.0, 300.0, ((50.0, 100.0),), 10.0, tabulated=table, own_response=True)
    assert band.with_shape(665.0, 30.0).tabulated is table
    moved = band.with_shape(670.0, 30.0)
    assert moved.tabulated is None and not moved.own_response
    assert Band("B4", 665.0, 30.0, 1.0, 50.0, 300.0, ((50.0, 100.0),), 10.0,
                tabulated=table).with_shape(665.0, 30.0).tabulated is None  # a scene's band: the model SRF
