"""The paper's atmospheric-band studies (`s2cl study NAME`): physics that can fail, on --quick settings."""

from __future__ import annotations

import json
import tomllib

import numpy as np
import pytest
from click.testing import CliRunner
from sixs_marks import sixs_test

from s2cl.cli.main import cli, main
from s2cl.errors import InputError
from s2cl.resources import scene_dir
from s2cl.scene.scene import Scene
from s2cl.studies import STUDIES, water_vapour
from s2cl.studies.aerosol import equal_error
from s2cl.studies.cirrus_spikes import (
    SPIKE_DIP,
    despiked_terms,
    isolated_spikes,
    remove_spikes,
    sixs_samples,
    spike_dips,
    spike_nodes,
)
from s2cl.studies.common import crossing, load_study


@pytest.fixture(scope="module")
def results(tmp_path_factory) -> dict[str, dict]:
    """Every study once, --quick, through the CLI; name -> its JSON."""
    out = tmp_path_factory.mktemp("studies")
    runner = CliRunner()
    data = {}
    for name in STUDIES:
        res = runner.invoke(cli, ["study", name, "--quick", "-o", str(out / name)])
        assert res.exit_code == 0, res.output
        stem = out / name / name
        assert stem.with_suffix(".png").stat().st_size > 1000
        data[name] = json.loads(stem.with_suffix(".json").read_text())
        assert ("s2cl vs Segl et al. 2012" in res.output) == bool(data[name]["key_figures"])
        assert data[name]["quick"] is True
    return data


def test_unknown_study_is_one_line_error(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["study", "nope"])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "unknown study 'nope'" in err and all(n in err for n in STUDIES)


def test_study_scenes_validate():
    for name in STUDIES:
        scene = Scene.load(f"study-{name}")
        assert scene.spec.study is not None and scene.spec.study.kind == name


def test_cirrus_radiance_falls_with_water_vapour(results):
    d = results["cirrus"]["data"]
    wl = np.array(d["wavelength_nm"])
    spectra = {float(k): np.array(v) for k, v in d["toa_radiance_1nm"].items()}
    bands = {float(k): np.array(v) for k, v in d["band_radiance"].items()}
    i = int(np.argmin(np.abs(wl - 1375)))
    assert spectra[1.0][i] < 0.5 * spectra[0.4][i]
    assert np.all(bands[1.0] < bands[0.4])              # every centre and width
    # 1375/30 band radiance near the 6S figures in the notes (1.48 / 0.43 W m-2 sr-1 um-1)
    assert d["band_1375_30"]["0.4"] == pytest.approx(1.48, rel=0.1)
    assert d["band_1375_30"]["1.0"] == pytest.approx(0.43, rel=0.1)
    # the darkest 30 nm band sits inside the 1.38 um absorption, far below the 1340 nm shoulder
    variants = np.array(d["variants"])
    w30 = variants[:, 1] == 30
    darkest = variants[w30][np.argmin(bands[1.0][w30]), 0]
    assert 1355 <= darkest <= 1400
    assert bands[1.0][w30].min() < 0.05 * spectra[1.0][np.argmin(np.abs(wl - 1340))]


# {{{ cirrus: 6S's isolated transmittance spikes


def _smooth_transmittance() -> np.ndarray:
    """exp(−τ) of a smooth absorption trough on the spike nodes (1357.5–1412.5 nm)."""
    lam = spike_nodes()
    return np.exp(-(2.0 + 3.0 * np.exp(-(((lam - 1385.0) / 15.0) ** 2))))


def test_spike_detector_leaves_a_smooth_curve_alone():
    t = _smooth_transmittance()
    assert isolated_spikes(t).size == 0
    out, passes = remove_spikes(t)
    assert passes == []
    np.testing.assert_array_equal(out, t)


def test_spike_detector_finds_spikes_and_a_shoulder_but_not_a_bump():
    t = _smooth_transmittance()
    spiky = t.copy()
    spiky[5] = t[5] ** 0.4                          # optical depth cut to 40 %: a spike
    spiky[12] = t[12] ** 0.8                        # cut to 80 %: a local maximum, but only a bump
    spiky[18], spiky[19] = t[18] ** 0.2, t[19] ** 0.5   # a spike with a shoulder
    dips = spike_dips(spiky)
    assert 0.1 < dips[12 - 1] < SPIKE_DIP           # the bump is a peak, below the threshold
    np.testing.assert_array_equal(isolated_spikes(spiky), [5, 18])
    out, passes = remove_spikes(spiky)
    assert passes == [[5, 18], [19]]                # the shoulder becomes a spike once 18 is gone
    assert out[12] == spiky[12]
    # replaced by the neighbours' geometric mean: back on the smooth curve within its curvature
    np.testing.assert_allclose(np.log(out[5]), np.log(t[5]), rtol=0.02)
    assert np.all(out <= spiky)
    assert isolated_spikes(out).size == 0


def test_sixs_samples_invert_the_linear_interpolation():
    nodes = spike_nodes()
    truth = np.random.default_rng(1).uniform(1e-3, 0.5, nodes.size)
    wl = np.arange(1340.0, 1431.0)
    samples, residual = sixs_samples(wl, np.interp(wl, nodes, truth), nodes)
    np.testing.assert_allclose(samples, truth, rtol=1e-9)
    assert residual < 1e-12
    coarse = np.arange(1340.0, 1431.0, 5.0)
    with pytest.raises(InputError, match="does not resolve"):
        sixs_samples(coarse, np.interp(coarse, nodes, truth), nodes)


def test_despiked_terms_split_rayleigh_from_what_water_absorbs():
    setup = load_study(Scene.load("study-cirrus"))
    state = setup.truth(water_vapour=1.0)
    terms, rayleigh = setup.terms(state), setup.terms(state.replace(aot550=0.0))
    nodes = spike_nodes()
    samples, residual = sixs_samples(terms.wavelength_nm, terms.t_water, nodes)
    assert residual < 1e-6                          # a LUT node: the 6S samples come back exactly
    same = despiked_terms(terms, rayleigh, nodes, samples)
    np.testing.assert_allclose(same.toa_radiance(0.3), terms.toa_radiance(0.3), rtol=1e-5)
    dark = despiked_terms(terms, rayleigh, nodes, np.full(nodes.size, 1e-12))
    inside = (terms.wavelength_nm >= nodes[0]) & (terms.wavelength_nm <= nodes[-1])
    # all water absorbed: only the Rayleigh path (6S: water above the aerosol) is left
    np.testing.assert_allclose(dark.toa_radiance(0.3)[inside], rayleigh.path_radiance[inside], rtol=1e-6)
    assert np.all(dark.toa_radiance(0.3)[inside] < terms.toa_radiance(0.3)[inside])
    np.testing.assert_allclose(dark.toa_radiance(0.3)[~inside], terms.toa_radiance(0.3)[~inside], rtol=1e-13)


def test_cirrus_sign_turns_only_when_all_spikes_go(results):
    d = results["cirrus"]["data"]
    c = d["change_pct"]
    for wv in ("0.4", "1.0"):
        spikes = d["spikes"]["per_water_vapour"][wv]
        assert spikes["removed_nm"] == [1385, 1390, 1397.5, 1400]
        # the threshold is not borderline: a clear margin to the dips removed and to those left
        assert spikes["largest_dip_left"] < SPIKE_DIP - 0.03 < SPIKE_DIP + 0.05 < min(spikes["dip_at_removal"].values())
        assert c["eq1"]["as_6s"][wv] > 10            # 6S as it is: 1380/30 brighter than 1375/30
        assert 0 < c["eq1"]["single_removed"][wv] < c["eq1"]["as_6s"][wv]   # 1397.5 nm alone: still brighter
        assert c["eq1"]["spikes_removed"][wv] < 0     # every isolated spike gone: darker, as in the paper
        assert c["gaussian"]["spikes_removed"][wv] < -10
        # the Gaussian's figure comes from its short-wave wing (the bright 1340 nm shoulder)
        wing, core, long_wing = d["change_pct_by_range"]["gaussian"]["spikes_removed"][wv]
        assert wing + core + long_wing == pytest.approx(c["gaussian"]["spikes_removed"][wv], abs=0.05)
        assert wing < 0.8 * c["gaussian"]["spikes_removed"][wv]
    # the sign needs both the 1390 and the 1397.5 nm spike gone, not the one at 1385 nm
    all_but = d["change_pct_per_spike"]["eq1"]["all_but"]
    assert min(all_but["1390"].values()) > 0 and min(all_but["1397.5"].values()) > 0
    assert max(all_but["1385"].values()) < 0


@sixs_test
def test_spikes_are_6s_own_samples():
    """The LUT's recovered 2.5 nm samples are 6S's printed H2O transmittances, spikes included."""
    from s2cl.atmos.sixs import SixSInput, run_many
    from s2cl.atmos.sixs_profiles import get_profile

    setup = load_study(Scene.load("study-cirrus"))
    terms = setup.terms(setup.truth(water_vapour=1.0))
    nodes = spike_nodes()
    lut, _ = sixs_samples(terms.wavelength_nm, terms.t_water, nodes)
    prof = get_profile("midlatitude_summer")
    runs = run_many([SixSInput(wavelength_um=nm / 1000.0, water_scale=1.0 / prof.water_column,
                               ozone_scale=330.0 / prof.ozone_column, aerosol="none") for nm in nodes])
    direct = np.array([o.gas["water"] for o in runs])
    np.testing.assert_allclose(lut, direct, atol=2e-5)     # 6S prints 5 decimals
    _, passes = remove_spikes(direct)
    assert sorted(float(nodes[k]) for p in passes for k in p) == [1385, 1390, 1397.5, 1400]


# }}}


def test_ozone_error_sign_flips_and_b3_largest(results):
    errs = results["ozone"]["data"]["band_error_pct"]
    bands = results["ozone"]["data"]["bands"]
    for rho in ("0.05", "0.15"):
        low, high = np.array(errs[f"250DU rho={rho}"]), np.array(errs[f"410DU rho={rho}"])
        assert np.all(low > 0) and np.all(high < 0)     # too little ozone assumed -> too bright, and back
        assert bands[int(np.argmax(np.abs(low)))] == "B3"
        assert bands[int(np.argmax(np.abs(high)))] == "B3"
    # darker targets suffer more (path radiance share)
    assert errs["250DU rho=0.05"][bands.index("B3")] > errs["250DU rho=0.15"][bands.index("B3")]
    assert 2.0 < errs["250DU rho=0.05"][bands.index("B3")] < 8.0


def test_methane_in_b11_below_one_percent(results):
    d = results["methane"]["data"]
    variants = np.array(d["variants"])
    t = np.array(d["band_transmittance"])
    nominal = t[(variants[:, 0] == 1610) & (variants[:, 1] == 90)][0]
    assert 0.99 < nominal < 1.0
    # ignoring the absorption makes every corrected reflectance too dark
    assert np.all(np.array(d["reflectance_error_pct"]) < 0)


def test_nominal_band_missing_from_sweep_is_an_error():
    data = tomllib.loads((scene_dir() / "study-methane.toml").read_text())
    data["sweep"]["ranges"]["B11"]["centres"] = [1600, 1620]
    setup = load_study(Scene.from_dict(data, base_dir=scene_dir()))
    with pytest.raises(InputError, match=r"sweep: the sweep lacks the nominal bands \(B11 1610/90 nm\)"):
        STUDIES["methane"](setup)


def test_crossing_is_linear_between_nodes():
    x = np.array([0.0, 1.0, 2.0, 3.0])
    f = np.array([[3.0, 1.0, -1.0, -3.0], [1.0, 2.0, 3.0, 4.0]])
    np.testing.assert_allclose(crossing(x, f), [1.5, 0.0])


def test_equal_error_interpolates_on_each_side():
    eps, rms = [-0.1, 0.0, 0.1], [20.0, 10.0, 30.0]
    assert equal_error(eps, rms, 20.0, +1) == pytest.approx(0.05)
    assert equal_error(eps, rms, 20.0, -1) == pytest.approx(0.1)
    assert np.isnan(equal_error(eps, rms, 40.0, +1))     # never reached
    assert equal_error(eps, rms, 5.0, -1) == 0.0         # reached at ε = 0 already


def _noise_free(name: str, **study_changes) -> Scene:
    data = tomllib.loads((scene_dir() / f"study-{name}.toml").read_text())
    data["effects"]["noise"] = False
    data["study"].update(study_changes)
    return Scene.from_dict(data, base_dir=scene_dir())


def test_apda_noise_free_recovers_water_vapour():
    scene = _noise_free("water-vapour", targets={"flat": "builtin:flat:0.1,0.3"},
                        water_vapour=[0.5, 1.0, 2.5], pixels=1)
    setup = load_study(scene)
    variants = {"B9": np.array([[945.0, 20.0], [920.0, 20.0]]), "B8a": np.array([[865.0, 20.0]])}
    weights = water_vapour.band_weights(setup, variants)
    truth = water_vapour.Truth(setup, water_vapour.SUMMER, variants, weights, setup.targets())
    axis = water_vapour.wv_axis(setup)
    terms = water_vapour.lut_terms(setup, water_vapour.SUMMER, axis, weights)
    for i9 in range(2):
        wv = water_vapour.retrieve(truth.radiance["B9"][i9], truth.radiance["B8a"][0], terms["B9"][i9],
                                   terms["B8a"][0], axis)
        np.testing.assert_allclose(wv[..., 0], np.broadcast_to(truth.truth, wv.shape[:2]), rtol=0.01)


def test_apda_with_noise_and_profile_mismatch(results):
    d = results["water-vapour"]["data"]
    flat = np.array(d["rel_rms_pct"]["flat"])
    assert 1.0 < flat.min() and flat.max() < 20 and np.median(flat) < 15   # sensor noise only: a few per cent
    w = d["winter"]
    assert w["summer_lut"]["vegetation"] > w["winter_lut"]["vegetation"]   # the wrong profile costs accuracy


def test_ddv_aerosol(results):
    d = results["aerosol"]["data"]
    assert d["rel_rms_pct_no_noise"] < 0.5              # exact factors, no noise: AOT recovered
    curve = dict(zip(d["factor_errors"], d["rel_rms_pct_vs_factor_error"], strict=True))
    assert curve[0.0] < curve[0.1] < curve[0.2]         # a wrong correlation factor grows the error
    assert d["rel_rms_pct_calibration"] > curve[0.0]    # +5 % calibration adds error


def test_stability_quick_run(results):
    """Every application's zero drift is its nominal error; the red-edge B6 (IGRM) is the tightest band."""
    d = results["stability"]["data"]
    zero, one = d["shifts_nm"].index(0.0), d["width_factors"].index(1.0)
    assert [a["kind"] for a in d["applications"]] == ["igrm", "gvmi", "sam"]
    for app in d["applications"]:
        for b in app["bands"]:
            assert app["error"]["shift"][b][zero] == app["nominal_error"]
            assert app["error"]["width"][b][one] == app["nominal_error"]
            assert set(app["requirement"][b]) == {"shift", "width"}
    igrm = d["applications"][0]
    b6 = igrm["requirement"]["B6"]["shift"]
    assert 0 < min(b6["minus"], b6["plus"]) < 1.0


def test_quick_may_only_replace_study_keys():
    data = tomllib.loads((scene_dir() / "study-ozone.toml").read_text())
    data["study"]["quick"] = {"kind": "cirrus"}
    with pytest.raises(InputError, match=r"study\.quick: quick cannot replace kind"):
        load_study(Scene.from_dict(data, base_dir=scene_dir()), quick=True)


def test_quick_typo_fails_without_quick():
    data = tomllib.loads((scene_dir() / "study-ozone.toml").read_text())
    data["study"]["quick"] = {"reflectances": [0.1]}
    with pytest.raises(InputError, match=r"quick cannot replace reflectances"):
        load_study(Scene.from_dict(data, base_dir=scene_dir()))


def test_relative_lut_path_resolves_against_the_scene(tmp_path):
    import shutil

    from s2cl.atmos.atmosphere import AtmosphereLUT

    lut = AtmosphereLUT.load()
    shutil.copy(lut.source, tmp_path / "my-lut.npz")
    data = tomllib.loads((scene_dir() / "study-methane.toml").read_text())
    data["atmosphere"]["lut"] = "my-lut.npz"
    setup = load_study(Scene.from_dict(data, base_dir=tmp_path))
    assert setup.lut.source == str(tmp_path / "my-lut.npz")
