"""The shipped 6S look-up table and the float64 atmosphere terms built from it."""

from __future__ import annotations

import json
import math
import shutil

import numpy as np
import pytest
from sixs_marks import sixs_test

from s2cl.atmos.atmosphere import AtmosphereLUT, default_lut_path
from s2cl.atmos.lut_format import FIXED_GASES, FORMAT_VERSION, fixed_gas_key
from s2cl.atmos.state import PAPER_AOT550, AtmosphereState, airmass, aot550_to_visibility, visibility_to_aot550
from s2cl.atmos.terms import GAS_NAMES
from s2cl.errors import InputError
from s2cl.grid import DEFAULT_GRID, SpectralGrid


@pytest.fixture(scope="module")
def lut() -> AtmosphereLUT:
    return AtmosphereLUT.load()


def raw(lut: AtmosphereLUT, key: str) -> np.ndarray:
    with np.load(lut.source) as npz:
        return npz[key].astype(np.float64)


def index_of(nm: float) -> int:
    return DEFAULT_GRID.index(nm)


# {{{ the shipped file


def test_shipped_lut_provenance_is_readable(lut):
    prov = lut.provenance
    assert prov["format"] == "s2cl-atmosphere-lut" and prov["format_version"] == FORMAT_VERSION
    assert prov["sixs_version"] == "1.1" and prov["sixs"].startswith("6SV1.1")
    # the command that built the shipped file (recorded then): the module of that time, or `s2cl lut build`
    assert prov["builder_command"].startswith(("python -m s2cl.lut_build", "s2cl lut build"))
    assert prov["created_utc"][:2] == "20" and prov["s2cl_version"]
    assert "2.5 nm" in prov["spectral_sampling"] and "1 nm" in prov["spectral_sampling"]
    assert prov["settings"]["aerosol_model"].startswith("continental")
    assert prov["build"]["seconds"] > 0 and sum(prov["build"]["sixs_runs"].values()) > 1000


def test_shipped_lut_is_small_float32_and_covers_the_brief(lut):
    assert default_lut_path().stat().st_size < 8 * 1024 * 1024
    with np.load(lut.source) as npz:
        assert all(npz[k].dtype == np.float32 for k in npz.files if npz[k].dtype.kind == "f")
    ax = lut.axes
    assert set(ax.profiles) == {"midlatitude_summer", "midlatitude_winter"}
    assert ax.aot550[0] == 0 and ax.aot550[-1] >= 0.8
    assert ax.ozone_range[0] <= 250 and ax.ozone_range[1] >= 410
    assert lut.water_vapour_range(0.0)[0] <= 0.2 and lut.water_vapour_range(60.0)[1] >= 5.0
    assert np.array_equal(ax.wavelength_nm, DEFAULT_GRID.wavelengths)


# }}}
# {{{ interpolation exact at nodes


def _by_hand(lut: AtmosphereLUT, ip: int, isza: int, iaot: int, iwv_ref: int) -> dict[str, np.ndarray]:
    """The formula evaluated on raw nodes (state at the reference zenith's water node)."""
    sza = lut.axes.solar_zenith[isza]
    m, m_ref = airmass(sza), airmass(lut.axes.reference_zenith)
    r = raw(lut, "path_reflectance_scattering")[ip, isza]
    t_water = raw(lut, "t_water")[ip, iwv_ref]
    t_nw = raw(lut, "t_ozone")[ip] ** (m / m_ref)
    for g in FIXED_GASES:
        t_nw = t_nw * raw(lut, fixed_gas_key(g))[ip, isza]
    t_gas = t_water * t_nw
    mu_s = math.cos(math.radians(sza))
    e0 = raw(lut, "e0")
    rho_path = r[0] * t_nw + (r[iaot] - r[0]) * t_gas
    g = mu_s * e0 / np.pi * t_gas * raw(lut, "t_down")[ip, isza, iaot] * raw(lut, "t_up")[ip, iaot]
    return {
        "path_radiance": mu_s * e0 / np.pi * rho_path,
        "ground_term": g,
        "s": raw(lut, "spherical_albedo")[ip, iaot],
    }


@pytest.mark.parametrize("method", ["linear", "nearest"])
@pytest.mark.parametrize(("profile", "sza", "aot", "wv_node"), [
    ("midlatitude_summer", 40.0, 5, 10),
    ("midlatitude_winter", 40.0, 0, 4),
    ("midlatitude_summer", 40.0, 11, 0),
    ("midlatitude_winter", 40.0, 3, 20),
])  # fmt: skip
def test_terms_are_exact_at_nodes(lut, method, profile, sza, aot, wv_node):
    ax = lut.axes
    state = AtmosphereState(
        profile=profile,
        water_vapour=float(ax.water_vapour[wv_node]),
        aot550=float(ax.aot550[aot]),
        ozone=ax.ozone_reference,
        solar_zenith=sza,
    )
    terms = lut.terms(state, method=method)
    want = _by_hand(lut, ax.profiles.index(profile), list(ax.solar_zenith).index(sza), aot, wv_node)
    np.testing.assert_allclose(terms.path_radiance, want["path_radiance"], rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(terms.ground_term, want["ground_term"], rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(terms.spherical_albedo, want["s"], rtol=1e-6, atol=0)


def test_other_zenith_nodes_are_exact_too(lut):
    """At SZA 60 the water node is reached through the slant column, so pick u = node * m_ref / m."""
    ax = lut.axes
    isza = list(ax.solar_zenith).index(60.0)
    wv = float(ax.water_vapour[12]) * airmass(ax.reference_zenith) / airmass(60.0)
    state = AtmosphereState(water_vapour=wv, aot550=float(ax.aot550[2]), ozone=ax.ozone_reference, solar_zenith=60.0)
    want = _by_hand(lut, 0, isza, 2, 12)
    np.testing.assert_allclose(lut.terms(state).path_radiance, want["path_radiance"], rtol=1e-6, atol=1e-9)


def test_linear_lies_between_neighbouring_nodes(lut):
    ax = lut.axes
    lo, hi = (AtmosphereState(aot550=float(ax.aot550[i])) for i in (6, 7))
    mid = AtmosphereState(aot550=float(ax.aot550[6] + ax.aot550[7]) / 2)
    a, b, c = (lut.terms(s).path_radiance for s in (lo, mid, hi))
    assert np.all((b >= np.minimum(a, c) - 1e-12) & (b <= np.maximum(a, c) + 1e-12))
    assert not np.allclose(b, a) and not np.allclose(b, c)


# }}}
# {{{ physics


def test_water_transmittance_at_945_decreases_with_water_vapour(lut):
    i = index_of(945)
    wvs = np.linspace(0.2, 5.0, 49)
    t = [lut.terms(AtmosphereState(water_vapour=float(w))).t_water[i] for w in wvs]
    assert np.all(np.diff(t) < 0)
    assert t[0] > 0.4 and t[-1] < 0.03  # 6S at 945 nm: 0.47 at 0.2 g/cm2, 0.019 at 5 g/cm2


def test_path_radiance_at_443_increases_with_aot(lut):
    i = index_of(443)
    aots = np.linspace(0.0, 1.0, 41)
    lp = [lut.terms(AtmosphereState(aot550=float(a))).path_radiance[i] for a in aots]
    assert np.all(np.diff(lp) > 0)


def test_ozone_lowers_transmittance_in_the_chappuis_band(lut):
    i = index_of(600)
    t = [lut.terms(AtmosphereState(ozone=o)).t_ozone[i] for o in (250.0, 330.0, 410.0)]
    assert t[0] > t[1] > t[2]
    assert t[0] ** (330 / 250) == pytest.approx(t[1], rel=1e-9)  # Beer's law


def test_gas_transmittances_multiply_to_the_total(lut):
    terms = lut.terms(AtmosphereState.paper_standard())
    product = np.prod([terms.transmittance[g] for g in GAS_NAMES], axis=0)
    np.testing.assert_allclose(terms.t_gas, product, rtol=1e-12)
    assert np.all((terms.t_methane > 0.5) & (terms.t_methane <= 1.0))
    assert terms.t_methane[index_of(2370)] < 0.8  # methane's 2.3 um band
    assert terms.t_methane[index_of(1610)] > 0.99 and terms.t_methane[index_of(1665)] < 0.99  # B11 edge


def test_winter_differs_from_summer_at_the_same_water_column(lut):
    summer = lut.terms(AtmosphereState(water_vapour=0.8))
    winter = lut.terms(AtmosphereState(profile="midlatitude_winter", water_vapour=0.8))
    i = index_of(945)
    assert summer.t_water[i] != pytest.approx(winter.t_water[i], rel=1e-3)


# }}}
# {{{ forward and inverse


@pytest.mark.parametrize("state", [
    AtmosphereState.paper_standard(),
    AtmosphereState(profile="midlatitude_winter", water_vapour=0.45, aot550=0.71, ozone=262.0, solar_zenith=57.0),
    AtmosphereState(water_vapour=4.2, aot550=0.0, ozone=480.0, solar_zenith=3.0),
])  # fmt: skip
def test_inverse_of_forward_is_identity(lut, state):
    terms = lut.terms(state, method="linear")
    rho = np.random.default_rng(7).uniform(0.0, 0.9, size=(5, DEFAULT_GRID.size))
    back = terms.surface_reflectance(terms.toa_radiance(rho))
    ok = terms.ground_term > 1e-6 * terms.path_radiance.max()
    np.testing.assert_allclose(back[:, ok], rho[:, ok], rtol=1e-10, atol=1e-12)


def test_forward_matches_6s_formula_written_out(lut):
    terms = lut.terms(AtmosphereState.paper_standard())
    rho = 0.3
    l_toa = terms.toa_radiance(np.full(DEFAULT_GRID.size, rho))
    by_hand = (
        terms.mu_s
        * terms.e0
        / np.pi
        * (terms.path_reflectance + terms.t_gas * terms.t_down * terms.t_up * rho / (1 - terms.spherical_albedo * rho))
    )
    np.testing.assert_allclose(l_toa, by_hand, rtol=1e-12)
    np.testing.assert_allclose(terms.toa_reflectance(rho), np.pi * l_toa / (terms.mu_s * terms.e0), rtol=1e-12)


def test_radiance_shape_must_match_the_grid(lut):
    terms = lut.terms(AtmosphereState())
    with pytest.raises(InputError, match="2101 wavelengths"):
        terms.toa_radiance(np.zeros(10))


# }}}
# {{{ bad input


@pytest.mark.parametrize(("changes", "key", "text"), [
    ({"aot550": 1.2}, "aot550", "aot550 = 1.2 is outside the LUT's range 0-1"),
    ({"solar_zenith": 70.0}, "solar_zenith", "solar_zenith = 70 deg is outside the LUT's range 0-60 deg"),
    ({"ozone": 150.0}, "ozone", "ozone = 150 DU is outside the LUT's range 200-500 DU"),
    ({"water_vapour": 6.0, "solar_zenith": 60.0}, "water_vapour", "water_vapour = 6 g/cm2 is outside"),
    ({"water_vapour": 0.1}, "water_vapour", "water_vapour = 0.1 g/cm2 is outside"),
])  # fmt: skip
def test_state_outside_the_lut_names_parameter_value_and_range(lut, changes, key, text):
    with pytest.raises(InputError) as info:
        lut.terms(AtmosphereState().replace(**changes))
    assert info.value.key == key and text in str(info.value)
    assert info.value.source == lut.source


def test_invalid_state_values_are_refused():
    with pytest.raises(InputError, match="water_vapour"):
        AtmosphereState(water_vapour=-1.0)
    with pytest.raises(InputError, match="allowed: midlatitude_summer"):
        AtmosphereState(profile="tropical")
    with pytest.raises(InputError, match="aot550"):
        AtmosphereState(aot550=float("nan"))


def test_grid_outside_the_lut_is_refused(lut):
    with pytest.raises(InputError) as info:
        lut.terms(AtmosphereState(), SpectralGrid(350.0, 2500.0, 1.0))
    assert info.value.key == "grid" and "400-2500 nm" in str(info.value)


def test_coarser_grid_is_interpolated_from_the_1nm_terms(lut):
    fine = lut.terms(AtmosphereState())
    coarse = lut.terms(AtmosphereState(), SpectralGrid(400.0, 2500.0, 5.0))
    take = np.searchsorted(fine.wavelength_nm, coarse.wavelength_nm)
    np.testing.assert_allclose(coarse.path_radiance, fine.path_radiance[take], rtol=1e-12)
    half = lut.terms(AtmosphereState(), SpectralGrid(400.5, 410.5, 1.0))
    np.testing.assert_allclose(half.ground_term, 0.5 * (fine.ground_term[0:11] + fine.ground_term[1:12]), rtol=1e-12)


def test_unknown_method_is_refused(lut):
    with pytest.raises(InputError, match="method"):
        lut.terms(AtmosphereState(), method="cubic")


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match="not found") as info:
        AtmosphereLUT.load(tmp_path / "absent.npz")
    assert str(tmp_path / "absent.npz") in str(info.value)


def test_corrupt_file_names_the_file(tmp_path):
    bad = tmp_path / "corrupt.npz"
    bad.write_bytes(b"this is not a zip archive" * 10)
    with pytest.raises(InputError, match="corrupt") as info:
        AtmosphereLUT.load(bad)
    assert info.value.source == str(bad)


def test_truncated_file_is_refused(tmp_path):
    cut = tmp_path / "cut.npz"
    data = default_lut_path().read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError, match="corrupt"):
        AtmosphereLUT.load(cut)


def _rewrite(tmp_path, edit) -> str:
    with np.load(default_lut_path()) as npz:
        arrays = {k: npz[k] for k in npz.files}
    edit(arrays)
    path = tmp_path / "edited.npz"
    np.savez(path, **arrays)
    return str(path)


def test_other_format_version_is_refused(tmp_path):
    def bump(arrays):
        prov = json.loads(str(arrays["provenance"]))
        prov["format_version"] = FORMAT_VERSION + 1
        arrays["provenance"] = np.array(json.dumps(prov))

    path = _rewrite(tmp_path, bump)
    with pytest.raises(InputError, match=f"format version {FORMAT_VERSION + 1}") as info:
        AtmosphereLUT.load(path)
    assert info.value.source == path and info.value.key == "provenance.format_version"


def test_missing_or_misshaped_array_is_refused(tmp_path):
    path = _rewrite(tmp_path, lambda a: a.pop("t_water"))
    with pytest.raises(InputError, match="missing arrays: t_water"):
        AtmosphereLUT.load(path)
    path = _rewrite(tmp_path, lambda a: a.update(t_down=a["t_down"][:, :, :-1]))
    with pytest.raises(InputError) as info:
        AtmosphereLUT.load(path)
    assert info.value.key == "t_down"


def test_a_copy_of_the_shipped_file_loads(tmp_path, lut):
    copy = tmp_path / "copy.npz"
    shutil.copy(default_lut_path(), copy)
    other = AtmosphereLUT.load(copy)
    np.testing.assert_array_equal(
        other.terms(AtmosphereState()).path_radiance, lut.terms(AtmosphereState()).path_radiance
    )


# }}}
# {{{ visibility


def test_paper_visibility_gives_6s_aot():
    assert visibility_to_aot550(23.0) == pytest.approx(0.23472, abs=1e-9)
    assert AtmosphereState.from_visibility(23.0).aot550 == PAPER_AOT550
    assert AtmosphereState.paper_standard().visibility_km == pytest.approx(23.0, rel=1e-9)
    assert aot550_to_visibility(visibility_to_aot550(37.0)) == pytest.approx(37.0, rel=1e-9)
    with pytest.raises(InputError, match="visibility_km"):
        visibility_to_aot550(2.0)


# }}}
# {{{ against 6S itself


@sixs_test
def test_rebuilt_slice_matches_the_shipped_file(tmp_path, lut):
    from s2cl.atmos.lut_axes import LUTAxes
    from s2cl.atmos.lut_build import build_lut

    axes = LUTAxes(
        profiles=("midlatitude_summer",),
        aot550=(0.0, PAPER_AOT550),
        solar_zenith=(40.0,),
        water_vapour=(1.5, 3.0),
        wavelength_range_nm=(935.0, 955.0),
    )
    path = tmp_path / "slice.npz"
    build_lut(path, axes, workers=2, progress=False, command="test")
    part = AtmosphereLUT.load(path)
    assert part.provenance["builder_command"] == "test"
    sel = slice(index_of(935), index_of(955) + 1)
    isza = list(lut.axes.solar_zenith).index(40.0)
    iaot = [0, list(lut.axes.aot550).index(np.float32(PAPER_AOT550))]
    iwv = [list(lut.axes.water_vapour).index(w) for w in (1.5, 3.0)]

    def close(key, shipped):
        np.testing.assert_allclose(raw(part, key), shipped, rtol=2e-6, atol=1e-9, err_msg=key)

    close("path_reflectance_scattering", raw(lut, "path_reflectance_scattering")[:1, isza : isza + 1, iaot, sel])
    close("t_down", raw(lut, "t_down")[:1, isza : isza + 1, iaot, sel])
    close("spherical_albedo", raw(lut, "spherical_albedo")[:1, iaot, sel])
    close("t_water", raw(lut, "t_water")[:1, iwv, sel])
    close("t_ozone", raw(lut, "t_ozone")[:1, sel])
    close("e0", raw(lut, "e0")[sel])
    for g in FIXED_GASES:
        close(fixed_gas_key(g), raw(lut, fixed_gas_key(g))[:1, isza : isza + 1, sel])


@sixs_test
def test_formula_matches_direct_6s_runs(lut):
    from s2cl.atmos.lut_validate import validate

    at_nodes = validate(lut, AtmosphereState.paper_standard(), (550.0, 945.0, 1375.0, 2190.0), (0.05, 0.6), workers=2)
    assert max(abs(r.relative_error) for r in at_nodes) < 3e-4
    between = AtmosphereState(
        profile="midlatitude_winter", water_vapour=0.7, aot550=0.12, ozone=280.0, solar_zenith=35.0
    )
    off_nodes = validate(lut, between, (665.0, 865.0, 1610.0), (0.3,), workers=2)
    assert max(abs(r.relative_error) for r in off_nodes) < 5e-3


# }}}
