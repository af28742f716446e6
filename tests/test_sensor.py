"""Sensor table (paper Table 1) and the shot-noise model."""

from __future__ import annotations

import numpy as np
import pytest

from s2cl.errors import InputError
from s2cl.sensor.noise_model import fit_noise_model
from s2cl.sensor.sensor import SENSOR_COLUMNS, Sensor


def test_table1_values() -> None:
    s = Sensor.sentinel2()
    assert s.band_names == ["B1", "B2", "B3", "B4", "B5", "B6", "B7", "B8", "B8a", "B9", "B10", "B11", "B12"]
    b = s.band("B8a")
    assert (b.centre_nm, b.fwhm_nm, b.lmin, b.lref, b.lmax, b.gsd_m) == (865, 20, 0.95, 52.4, 307.8, 20)
    assert s.band("B12").snr_points == ((1.7, 100.0), (22.8, 510.0))
    assert s.band("B10").snr_points == ((6.0, 50.0),)
    assert s.bits == 12


def test_noise_model_reproduces_table1_snr() -> None:
    worst = 0.0
    for b in Sensor.sentinel2().bands:
        for L, snr in b.snr_points:
            worst = max(worst, abs(float(b.noise.snr(L)) / snr - 1))
    assert worst < 0.03, f"worst relative SNR misfit {worst:.3%}"


def test_noise_model_is_shot_noise_affine() -> None:
    m = fit_noise_model([(10.0, 10.0), (100.0, 50.0), (1000.0, 200.0)], 20.0)
    assert m.a >= 0 and m.b >= 0
    one = fit_noise_model([(6.0, 50.0)], 30.0)
    assert one.a == 0.0
    assert float(one.snr(24.0)) == pytest.approx(100.0)  # SNR ∝ √L with one point


def test_width_scaling_of_snr() -> None:
    b = Sensor.sentinel2().band("B5")
    narrow = b.with_shape(705, 15 / 4)
    ratio = float(narrow.noise.snr(74.6, narrow.fwhm_nm) / b.noise.snr(74.6, b.fwhm_nm))
    assert ratio == pytest.approx(0.5)  # 4x narrower: half the SNR, twice the NER


def test_bad_snr_points() -> None:
    with pytest.raises(InputError):
        fit_noise_model([], 10.0)
    with pytest.raises(InputError):
        fit_noise_model([(0.0, 10.0)], 10.0)


def _write(tmp_path, rows: list[str], header: str = ",".join(SENSOR_COLUMNS)):
    path = tmp_path / "sensor.csv"
    path.write_text(header + "\n" + "\n".join(rows) + "\n")
    return path


GOOD = "B4,665,30,3.31,108,484.1,7.7,142,357.9,10"


@pytest.mark.parametrize(
    ("row", "key"),
    [("B4,665,0,3.31,108,484.1,7.7,142,357.9,10", "B4.fwhm_nm"),
     ("B4,665,-3,3.31,108,484.1,7.7,142,357.9,10", "B4.fwhm_nm"),
     ("B4,665,30,500,108,484.1,7.7,142,357.9,10", "B4.lmin"),
     ("B4,665,30,3.31,108,484.1,,,,10", "B4.snr"),
     ("B4,665,30,abc,108,484.1,7.7,142,357.9,10", "B4.lmin"),
     ("B4,665,30,3.31,108,484.1,7.7,142,357.9,0", "B4.gsd_m"),
     ("B4,nan,30,3.31,108,484.1,7.7,142,357.9,10", "B4.centre_nm")],
)
def test_bad_sensor_rows_name_file_band_and_key(tmp_path, row: str, key: str) -> None:
    path = _write(tmp_path, [row])
    with pytest.raises(InputError) as err:
        Sensor.from_csv(path)
    assert str(path) in str(err.value) and key in str(err.value)


def test_sensor_file_errors(tmp_path) -> None:
    with pytest.raises(InputError, match="missing columns"):
        Sensor.from_csv(_write(tmp_path, ["B4,665"], header="band,centre_nm"))
    with pytest.raises(InputError, match="duplicate"):
        Sensor.from_csv(_write(tmp_path, [GOOD, GOOD]))
    with pytest.raises(InputError, match="not found"):
        Sensor.from_csv(tmp_path / "missing.csv")
    with pytest.raises(InputError, match="bits"):
        Sensor.from_csv(_write(tmp_path, [GOOD]), bits=17)
    with pytest.raises(InputError, match="bits"):
        Sensor.sentinel2().with_bits(0)


def test_select_and_arrays() -> None:
    s = Sensor.sentinel2().select(["B4", "b5"])
    assert s.band_names == ["B4", "B5"]
    assert np.allclose(s.array("lmin"), [3.31, 2.61])
    with pytest.raises(InputError, match="no band"):
        s.band("B8")


def test_optional_numeric_columns_and_measured_noise_coefficients(tmp_path) -> None:
    """A sensor table's extra numeric columns reach each band (a text column is ignored, as before); measured
    ``noise_alpha``, ``noise_beta`` (σ² = α² + β·L at the band's width) replace the fit to the SNR points."""
    header = ",".join(SENSOR_COLUMNS) + ",noise_alpha,noise_beta,note"
    rows = ["B4,665,30,3.31,50,484.1,,142,,10,0.12,0.004,red", "B5,705,15,2.61,50,449.6,,117,,20,,,rededge"]
    (tmp_path / "s.csv").write_text("\n".join([header, *rows]) + "\n")
    s = Sensor.from_csv(tmp_path / "s.csv")
    b4, b5 = s.band("B4"), s.band("B5")
    assert dict(b4.extra) == {"noise_alpha": 0.12, "noise_beta": 0.004} and dict(b5.extra) == {}
    assert b4.noise.a == pytest.approx(0.12**2, rel=1e-15) and b4.noise.b == 0.004
    assert b4.noise_coefficients() == pytest.approx((0.0144, 0.004), rel=1e-15)
    assert b4.with_shape(665, 60).noise_coefficients() == pytest.approx((0.0072, 0.002), rel=1e-15)
    fitted = fit_noise_model([(50.0, 117.0)], 15.0)
    assert (b5.noise.a, b5.noise.b) == (fitted.a, fitted.b)
