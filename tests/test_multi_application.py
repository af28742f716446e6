"""A scene with several applications (``[[application]]``, issue 35 items 1-2): each application's score of a design
equals, bit for bit, what ``optimise`` of that application's own single-application scene gives for the same design
and seed; the joint table holds the product of the applications' sub-spaces; a killed run resumes to the same
bytes; bad input is one line naming the scene file and the key."""

from __future__ import annotations

import json
import tomllib

import numpy as np
import pandas as pd
import pytest

import s2cl
from s2cl.app.optimise import count_sweep
from s2cl.errors import InputError
from s2cl.retrieve.metric import CLASSIFICATION, REGRESSION
from s2cl.scene.applications import scene_applications, target_value
from s2cl.scene.scene import Scene

# chlorophyll (IGRM on B4-B7, Lib1) and leaf water (GVMI on B8/B11, the leaf-water library) share B5, B6 and B11:
# chlorophyll's sub-space is B5 × B6 (4 × 3 = 12 designs, B4 and B7 at the sensor's own 665/30 and 783/20 nm),
# leaf water's is B11 (2 × 2 = 4, B8 at 842/115 nm): the joint space has 12 × 4 = 48 designs
COMMON = """
[scene]
name = "two"
[surface]
library = "builtin:lib1"
quantity = "reflectance"
copies = 2
[effects]
atmosphere = true
correct = true
seed = 3
"""
# B5 and B6 share the centre 705 nm in 2 of chlorophyll's designs: IGRM cannot fit them (3 distinct centres)
RANGES = {"B5": "{ centres = [700, 705], widths = [15, 20] }", "B6": "{ centres = [705, 740, 745], widths = [15] }",
          "B11": "{ centres = [1600, 1640], widths = [50, 100] }"}
TWO = COMMON + """
[[application]]
name = "chlorophyll"
target = "5 ug/cm2"
[application.analysis]
kind = "igrm"
parameter = "cab"
bands = ["B4", "B5", "B6", "B7"]
[[application]]
name = "leaf_water"
library = "builtin:leaf-water"
copies = 3
target = 40
analysis = { kind = "gvmi", parameter = "ewt", nir = "B8", swir = "B11" }
[sweep]
bands = ["B5", "B6", "B11"]
within_noise_top = 0
[sweep.ranges]
""" + "".join(f"{b} = {r}\n" for b, r in RANGES.items())

# each application's own scene, written by hand: its [analysis], library and copies, its [sweep] over its bands
CHLOROPHYLL = COMMON + """
[analysis]
kind = "igrm"
parameter = "cab"
bands = ["B4", "B5", "B6", "B7"]
[sweep]
bands = ["B4", "B5", "B6", "B7"]
within_noise_top = 0
[sweep.ranges]
B4 = { centre = 665, width = 30 }
B7 = { centre = 783, width = 20 }
""" + "".join(f"{b} = {RANGES[b]}\n" for b in ("B5", "B6"))
LEAF_WATER = COMMON.replace('"builtin:lib1"', '"builtin:leaf-water"').replace("copies = 2", "copies = 3") + f"""
[analysis]
kind = "gvmi"
parameter = "ewt"
nir = "B8"
swir = "B11"
[sweep]
bands = ["B8", "B11"]
within_noise_top = 0
[sweep.ranges]
B8 = {{ centre = 842, width = 115 }}
B11 = {RANGES["B11"]}
"""


def _write(tmp_path, name: str, text: str):  # type: ignore[no-untyped-def]
    path = tmp_path / f"{name}.toml"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def runs(tmp_path_factory):  # type: ignore[no-untyped-def]
    """The two-application sweep and each application's own sweep, run once for the module's tests."""
    tmp = tmp_path_factory.mktemp("multi")
    out = {name: s2cl.optimise(_write(tmp, name, text), tmp / name)
           for name, text in (("two", TWO), ("chlorophyll", CHLOROPHYLL), ("leaf_water", LEAF_WATER))}
    return tmp, out


def _table(result) -> pd.DataFrame:  # type: ignore[no-untyped-def]
    return pd.read_parquet(result.folder / "results.parquet")


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    """Equal bit for bit (NaN where NaN)."""
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def test_each_score_equals_its_own_scene_bit_for_bit(runs) -> None:  # type: ignore[no-untyped-def]
    _, out = runs
    joint, chl, water = _table(out["two"]), _table(out["chlorophyll"]), _table(out["leaf_water"])
    assert len(joint) == len(chl) * len(water) == 48  # the product of the sub-spaces
    # each joint design's own designs found by its band shapes (not by the code's numbering)
    keys_c = ["B5_centre_nm", "B5_width_nm", "B6_centre_nm", "B6_width_nm"]
    keys_w = ["B11_centre_nm", "B11_width_nm"]
    with_c = joint.merge(chl, on=keys_c, how="left", suffixes=("", "_own"), validate="many_to_one")
    with_w = joint.merge(water[[*keys_w, "rms", "underdetermined"]], on=keys_w, how="left", suffixes=("", "_own"),
                         validate="many_to_one")
    assert chl["underdetermined"].sum() == 2 and not water["underdetermined"].any()
    unfit = with_c["underdetermined_own"].to_numpy()
    assert unfit.sum() == 2 * len(water)
    # NaN where chlorophyll cannot fit the design (the sweep leaves those out of its ranking), else its own score
    assert _same(with_c["chlorophyll_rms"].to_numpy(), np.where(unfit, np.nan, with_c["rms_own"].to_numpy()))
    assert np.isnan(with_c["chlorophyll_rms"].to_numpy()[unfit]).all() and np.isfinite(with_c["rms_own"][unfit]).all()
    assert _same(with_w["leaf_water_rms"].to_numpy(), with_w["rms_own"].to_numpy())
    # the first application's whole row is the joint row's (ranking, heatmaps and the reference read it)
    for column in ("rms", "r2", "robust_rms", "failed_fraction", "bound_fraction", "underdetermined"):
        assert _same(with_c[column].to_numpy(), with_c[f"{column}_own"].to_numpy()), column
    assert joint["leaf_water_rms"].dtype == np.float64
    assert np.unique(joint[keys_c + keys_w].to_numpy(), axis=0).shape[0] == 48  # every design once
    assert list(joint["config"]) == list(range(48))


def test_joint_configurations_map_to_each_application_s_own(runs, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """The prepared sweep exposes, per application, its checked scene, its job and the map from joint configuration
    numbers to its own: the application's row at the mapped number has the joint row's shapes of its bands."""
    from s2cl.app.optimise import prepare

    _, out = runs
    prepared = prepare(out["two"].folder / ".." / "two.toml", tmp_path / "p", workers=None, scheduler=None,
                       overwrite=False, chunk=None, device=None, max_memory=None)
    multi = prepared.applications
    assert multi is not None and [a.name for a in multi.apps] == ["chlorophyll", "leaf_water"]
    assert prepared.job is multi.first.job and prepared.checked is multi.first.checked
    joint = _table(out["two"])
    for a, bands in zip(multi.apps, (["B5", "B6"], ["B11"]), strict=True):
        assert a.checked.scene.spec.analysis.kind == a.part.app.analysis.kind and a.job.n_configs == {
            "chlorophyll": 12, "leaf_water": 4}[a.name]
        own = pd.read_parquet(out["two"].folder / "applications" / a.name / "results.parquet").set_index("config")
        mapped = own.loc[a.configs_of(joint["config"].to_numpy())]
        for b in bands:
            for s in ("centre_nm", "width_nm"):
                assert (mapped[f"{b}_{s}"].to_numpy() == joint[f"{b}_{s}"].to_numpy()).all()
        assert _same(np.where(mapped["underdetermined"], np.nan, mapped["rms"]), joint[a.column].to_numpy())
    assert not (tmp_path / "p").exists()


def test_summary_records_each_application(runs) -> None:  # type: ignore[no-untyped-def]
    _, out = runs
    summary = json.loads((out["two"].folder / "summary.json").read_text(encoding="utf-8"))
    chl, water = summary["applications"]
    assert (chl["name"], chl["kind"], chl["parameter"], chl["metric"], chl["column"], chl["target"]) == \
        ("chlorophyll", "igrm", "cab", "rms", "chlorophyll_rms", 5.0)
    assert (water["name"], water["kind"], water["parameter"], water["column"], water["target"]) == \
        ("leaf_water", "gvmi", "ewt", "leaf_water_rms", 40.0)
    assert chl["units"] == "µg/cm²" and water["units"] == "µm"
    # the reference is the sensor's own bands' score: chlorophyll's own design (705/15, 740/15) is in its sweep
    own_c = _table(out["chlorophyll"])
    row = own_c[(own_c["B5_centre_nm"] == 705) & (own_c["B5_width_nm"] == 15) & (own_c["B6_centre_nm"] == 740)]
    assert chl["reference"] == float(row["rms"].iloc[0]) == summary["reference"]["rms"]
    # leaf water's own B11 (1610/90) is not: its reference is the one-design sweep of its own scene's reference
    assert water["reference"] == out["leaf_water"].summary["reference"]["rms"]
    assert summary["metric"] == "rms" and summary["configurations"] == 48
    assert summary["bands"] == ["B5", "B6", "B11"]
    # a heatmap per moving band; B11's (chlorophyll does not read it) of leaf water's column
    assert {p.name for p in out["two"].written} >= {f"heatmap_{b}.png" for b in ("B5", "B6", "B11")}


def test_a_killed_run_resumes_to_the_same_bytes(tmp_path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """Interrupted while it writes the joint table (after one of its chunks), with one of an application's chunks
    lost too: the same call finishes it, and results.parquet is the uninterrupted run's, byte for byte."""
    import s2cl.sweep.joint as joint

    monkeypatch.setattr(joint, "JOINT_CHUNK", 10)
    scene = _write(tmp_path, "two", TWO)
    whole = s2cl.optimise(scene, tmp_path / "whole")
    real, written = joint.write_chunk, []

    def dies(out, lo, rows):  # type: ignore[no-untyped-def]
        if written:
            raise KeyboardInterrupt
        written.append(lo)
        return real(out, lo, rows)

    monkeypatch.setattr(joint, "write_chunk", dies)
    with pytest.raises(KeyboardInterrupt):
        s2cl.optimise(scene, tmp_path / "killed")
    monkeypatch.setattr(joint, "write_chunk", real)
    folder = tmp_path / "killed"
    assert not (folder / "results.parquet").exists() and len(list((folder / "chunks").glob("*.parquet"))) == 1
    next(iter((folder / "applications" / "leaf_water" / "chunks").glob("*.parquet"))).unlink()
    again = s2cl.optimise(scene, folder)
    assert len(list((folder / "chunks").glob("*.parquet"))) == 5  # 48 designs in chunks of 10
    assert (folder / "results.parquet").read_bytes() == (whole.folder / "results.parquet").read_bytes()
    assert again.summary["applications"] == whole.summary["applications"]


def test_the_first_application_is_tested_within_noise_on_its_own_designs(tmp_path) -> None:
    """within_noise_top on a joint ranking: its designs are the joint configurations, scored on the first
    application's own job (designs differing only in a band it does not read are within noise of each other)."""
    scene = _write(tmp_path, "two", TWO.replace("within_noise_top = 0", "within_noise_top = 4"))
    result = s2cl.optimise(scene, tmp_path / "out")
    tested = result.summary["within_noise"]
    joint = _table(result)
    assert [d["config"] for d in tested["designs"]] == [e["config"] for e in result.summary["top"][:4]]
    for d in tested["designs"]:
        row = joint[joint["config"] == d["config"]].iloc[0]
        assert d["bands"]["B11"] == [row["B11_centre_nm"], row["B11_width_nm"]]
        assert d["rms"] == row["rms"]
    best = tested["designs"][0]["bands"]
    same_b56 = [d for d in tested["designs"][1:] if (d["bands"]["B5"], d["bands"]["B6"]) == (best["B5"], best["B6"])]
    assert all(d["within"] and d["difference"] == 0 for d in same_b56)


# -- requirements ---------------------------------------------------------------------------------------------

def _app(target):  # type: ignore[no-untyped-def]
    text = TWO.replace('target = "5 ug/cm2"', f"target = {json.dumps(target)}")
    return scene_applications(Scene.from_dict(tomllib.loads(text)))[0]


@pytest.mark.parametrize("target, value", [(5, 5.0), (4.5, 4.5), ("5 ug/cm2", 5.0), ("5 µg/cm²", 5.0),
                                           ("5µg/cm2", 5.0), ("6.5", 6.5), ("1e1 UG/CM2", 10.0)])
def test_a_target_is_a_number_in_the_metric_units(target, value) -> None:  # type: ignore[no-untyped-def]
    assert target_value(_app(target), REGRESSION) == value


@pytest.mark.parametrize("target, metric, words", [
    ("5 %", REGRESSION, "application[0].target: '5 %' is in '%', but the RMS of cab is in µg/cm²"),
    ("5 ug/cm2", CLASSIFICATION, "is in 'ug/cm2', but the omission error is in %"),
    ("five", REGRESSION, "'five' is not a requirement: give a number in µg/cm²"),
    (-1, REGRESSION, "must be a finite score ≥ 0"),
])
def test_a_target_in_other_units_is_one_line(target, metric, words) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(InputError) as err:
        target_value(_app(target), metric)
    assert words in str(err.value) and "\n" not in str(err.value)


def test_a_percent_target_for_a_classification() -> None:
    assert target_value(_app("10 %"), CLASSIFICATION) == 10.0


# -- bad input: one line, the scene file and the key, nothing created ------------------------------------------

@pytest.mark.parametrize("edit, key, words", [
    (lambda t: t.replace('bands = ["B4", "B5", "B6", "B7"]', 'bands = ["B4", "B5", "B6", "B14"]'),
     "application[0].analysis.bands", "needs band 'B14', which no swept or fixed band provides"),
    (lambda t: t.replace('nir = "B8"', 'nir = "B13"'), "application[1].analysis.nir", "needs band 'B13'"),
    (lambda t: t.replace('"builtin:leaf-water"', '"builtin:nope"'), "application[1].library", "nope"),
    (lambda t: t.replace('parameter = "ewt"', 'parameter = "wet"'), "application[1].analysis.parameter",
     "library has no parameter 'wet'"),
    (lambda t: t.replace('target = "5 ug/cm2"', 'target = "5 %"'), "application[0].target", "µg/cm²"),
    (lambda t: t.replace("within_noise_top = 0", 'within_noise_top = 0\nsearch = "halving"\nsearch_start = 100')
     .replace("centres = [1600, 1640]", "centres = [1600, 1610, 1620, 1630, 1640]"), "sweep.search_start",
     "covers at most search_start = 100 joint designs; this [sweep] has 120"),
    (lambda t: t.replace('bands = ["B5", "B6", "B11"]', 'bands = ["B5", "B6", "B11", "B12"]')
     + 'B12 = { centres = [2190, 2200], widths = [20] }\n', "sweep.bands", "B12 is swept but no application reads it"),
    (lambda t: t.replace('name = "leaf_water"', 'name = "robust"'), "application[1].name",
     "its score column robust_rms is a column of the results already"),
])
def test_bad_applications_are_one_line(tmp_path, edit, key, words) -> None:  # type: ignore[no-untyped-def]
    scene = _write(tmp_path, "bad", edit(TWO))
    with pytest.raises(InputError) as err:
        s2cl.optimise(scene, tmp_path / "out")
    message = str(err.value)
    assert message.startswith(f"{scene}: {key}: ") and words in message and "\n" not in message, message
    assert not (tmp_path / "out").exists()


def test_a_joint_space_too_large_is_refused_in_one_line(tmp_path, monkeypatch) -> None:
    import s2cl.app.applications as applications

    monkeypatch.setattr(applications, "MAX_JOINT", 40)
    scene = _write(tmp_path, "big", TWO)
    with pytest.raises(InputError) as err:
        s2cl.optimise(scene, tmp_path / "out")
    message = str(err.value)
    assert message.startswith(f"{scene}: sweep: the joint space has 48 designs") and "\n" not in message
    assert not (tmp_path / "out").exists()


def test_sweep_count_counts_the_joint_space(tmp_path) -> None:
    scene = _write(tmp_path, "two", TWO)
    seen = []
    count = count_sweep(scene, on_counted=lambda name, variants, n: seen.append((variants, n)))
    assert count.configurations == 48 == seen[0][1]
    assert count.underdetermined == 2 * 4  # chlorophyll's two (B5 = B6 = 705 nm) with each of leaf water's four
    assert [(v["band"], v["variants"]) for v in count.variants] == [("B5", 4), ("B6", 3), ("B11", 4)]
    assert not (tmp_path / "two").exists()


def test_a_study_of_an_application_scene_is_refused_in_one_line(tmp_path) -> None:
    """Commands that take one [analysis] (check_sweep: the studies) name where such a scene runs."""
    from s2cl.app.checks import check_sweep

    scene = _write(tmp_path, "two", TWO)
    with pytest.raises(InputError, match=r"application: a scene with \[\[application\]\] tables runs with s2cl "
                                         "optimise, sweep run or sweep count"):
        check_sweep(Scene.load(scene))


def test_sweep_report_keeps_the_applications(runs) -> None:  # type: ignore[no-untyped-def]
    """``s2cl sweep report`` of a finished multi-application sweep ranks it again and keeps its records."""
    from s2cl.app.optimise import report_results

    _, out = runs
    summary, written = report_results(out["two"].folder)
    assert summary["applications"] == out["two"].summary["applications"]
    before = out["two"].summary

    def plain(entries):  # type: ignore[no-untyped-def]  # the report marks untested designs within_noise: null
        return [{k: v for k, v in e.items() if k != "within_noise"} for e in entries]

    assert plain(summary["top"]) == plain(before["top"])
    assert plain([summary["reference"]]) == plain([before["reference"]])
    assert {p.name for p in written} >= {"summary.json", "heatmap_B11.png"}


def test_optimise_writes_the_pareto_front_a_brute_force_dominance_test_finds(runs) -> None:  # type: ignore[no-untyped-def]
    """The trade-off wired into ``s2cl optimise``: ``summary["pareto"]`` and the ``pareto`` column of
    ``results.parquet`` hold exactly the designs no other design dominates, by a plain pairwise test written here
    (the rule of docs/pareto.md with the margins the run recorded), and the figure is written."""
    _, out = runs
    summary, table = out["two"].summary, _table(out["two"])
    record = summary["pareto"]
    columns = ["chlorophyll_rms", "leaf_water_rms"]
    margins = [record["margins"][a]["margin"] for a in ("chlorophyll", "leaf_water")]
    rows = [(int(c), [float(v) for v in vals]) for c, *vals in table[["config", *columns]].itertuples(index=False)]
    rankable = [(c, s) for c, s in rows if all(np.isfinite(s))]  # a design an application cannot fit is never on it

    def dominates(a: list[float], b: list[float]) -> bool:
        return all(x <= y for x, y in zip(a, b, strict=True)) and any(
            y - x > m for x, y, m in zip(a, b, margins, strict=True))

    expected = {c for c, s in rankable if not any(dominates(t, s) for _, t in rankable)}
    assert expected and set(record["front"]["configs"]) == expected
    assert set(table.loc[table["pareto"], "config"]) == expected
    assert record["designs"] == len(rankable)
    assert (out["two"].folder / "pareto.png").exists()
    assert "pareto" not in summary["top"][0]  # a ranking entry is a design's own values


OWN_GRID = COMMON.replace('"builtin:lib1"', '"builtin:leaf-water"').replace("copies = 2", "copies = 3") + """
[[application]]
name = "leaf_water"
analysis = { kind = "gvmi", parameter = "ewt", nir = "B8", swir = "B11" }
[[application]]
name = "minerals"
library = "builtin:minerals-swir"
grid = { start_nm = 1500, stop_nm = 2500 }
[application.analysis]
kind = "sam"
classes = ["Al-OH", "Mg-OH/C-O"]
bands = ["B11", "B12"]
[sweep]
bands = ["B11", "B12"]
within_noise_top = 0
[sweep.ranges]
B11 = { centres = [1600, 1640], widths = [50, 75] }
B12 = { centres = [2190, 2210], widths = [30, 80] }
"""
# the minerals application's own scene as the paper's Table 6 writes one (scenes/table6-b12.toml): its grid and the
# sensor's bands that lie on it
MINERALS = COMMON.replace('"builtin:lib1"', '"builtin:minerals-swir"').replace("copies = 2", "copies = 3") + """
[grid]
start_nm = 1500
stop_nm = 2500
[sensor]
bands = ["B11", "B12"]
[analysis]
kind = "sam"
classes = ["Al-OH", "Mg-OH/C-O"]
bands = ["B11", "B12"]
[sweep]
bands = ["B11", "B12"]
within_noise_top = 0
[sweep.ranges]
B11 = { centres = [1600, 1640], widths = [50, 75] }
B12 = { centres = [2190, 2210], widths = [30, 80] }
"""


def test_an_application_on_its_own_grid_is_its_own_scene_bit_for_bit(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """``grid`` of an application (a library on part of the spectrum): its scores equal, bit for bit, those of its
    own scene on that grid with the sensor's bands that lie on it; the other application keeps the scene's grid."""
    joint = s2cl.optimise(_write(tmp_path, "own_grid", OWN_GRID), tmp_path / "joint")
    alone = s2cl.optimise(_write(tmp_path, "minerals", MINERALS), tmp_path / "alone")
    keys = ["B11_centre_nm", "B11_width_nm", "B12_centre_nm", "B12_width_nm"]
    both = _table(joint).merge(_table(alone)[[*keys, "omission_error_pct"]], on=keys, validate="one_to_one")
    assert len(both) == 16
    assert _same(both["minerals_omission_error_pct"].to_numpy(), both["omission_error_pct"].to_numpy())
    assert np.isfinite(both["leaf_water_rms"]).all()


@pytest.mark.parametrize("grid, words", [
    ("{ start_nm = 2400, stop_nm = 2500 }", "no band of the sensor lies on the grid"),
    ("{ start_nm = 1500, stop_nm = 2000 }", "B12 (which the application reads) does not lie on its grid"),
    ("{ start_nm = 2500, stop_nm = 1500 }", "start"),
])
def test_an_application_grid_that_cannot_hold_its_bands_is_one_line(tmp_path, grid, words) -> None:  # type: ignore[no-untyped-def]
    text = OWN_GRID.replace("grid = { start_nm = 1500, stop_nm = 2500 }", f"grid = {grid}")
    with pytest.raises(InputError) as err:
        s2cl.optimise(_write(tmp_path, "bad_grid", text), tmp_path / "out")
    message = str(err.value)
    assert words in message and "\n" not in message and "application[1]" in message, message
    assert not (tmp_path / "out").exists()
