"""Sensor table (paper Table 1) and the shot-noise model."""

from __future__ import annotations

import numpy as np
import pytest

from s2cl.errors import InputError
from s2cl.sensor.noise_model import fit_noise_model, nnls_two
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


def _weighted(points: list[tuple[float, float]]) -> tuple[np.ndarray, np.ndarray]:
    """The noise model's least-squares problem, written out again: rows (1, L) / σ², target σ² / σ²."""
    L = np.array([p[0] for p in points])
    var = (L / np.array([p[1] for p in points])) ** 2
    return np.stack([1 / var, L / var], axis=1), var / var


def _kkt(D: np.ndarray, y: np.ndarray, x: tuple[float, float]) -> None:
    """The optimality conditions of non-negative least squares, checked at ``x``: feasible, the gradient
    Dᵀ(Dx − y) zero along a positive coefficient and pointing into the quadrant (≥ 0) at one on its bound."""
    x_ = np.array(x)
    grad = D.T @ (D @ x_ - y)
    scale = np.abs(D.T) @ (np.abs(D) @ np.abs(x_) + np.abs(y))  # the size of the terms the gradient sums
    assert (x_ >= 0).all()
    for k in range(2):
        if x_[k] > 0:
            assert abs(grad[k]) <= 1e-12 * scale[k], (k, grad, x)
        else:
            assert grad[k] >= -1e-12 * scale[k], (k, grad, x)


@pytest.mark.parametrize("points, bound", [
    ([(10.0, 10.0), (100.0, 50.0), (1000.0, 200.0)], None),  # both terms positive
    ([(10.0, 10 / np.sqrt(0.5)), (100.0, 100 / np.sqrt(9.5))], "a"),  # the line through both: a = -0.5 < 0
    ([(10.0, 5.0), (100.0, 100.0)], "b"),  # σ² falls with L: b < 0 unconstrained
    ([(10.0, 5.0), (100.0, 100.0), (1000.0, 2000.0)], "b"),
    ([(1.0, 1.0), (2.0, 100.0), (3.0, 1000.0)], "b"),
])
def test_nnls_two_against_scipy_and_the_optimality_conditions(points, bound) -> None:
    """The exact two-unknown solver against an independent one (scipy's Lawson–Hanson active set) and the KKT
    conditions, on fits inside the quadrant and with either coefficient at its bound (where the hand-made tables
    put it: ``bound``)."""
    from scipy.optimize import nnls

    D, y = _weighted(points)
    x = nnls_two(D, y)
    want, _ = nnls(D, y)
    np.testing.assert_allclose(x, want, rtol=1e-12, atol=1e-300)
    _kkt(D, y, x)
    if bound is not None:
        assert x[0 if bound == "a" else 1] == 0.0 and x[1 if bound == "a" else 0] > 0
    else:
        assert min(x) > 0
    model = fit_noise_model(points, 10.0)
    np.testing.assert_allclose((model.a, model.b), x, rtol=1e-14, atol=1e-300)


def test_nnls_two_on_random_tables() -> None:
    """300 random tables of 2–5 points (SNR anywhere from 1 to 1000 at L from 0.1 to 1000): the same residual as scipy's
    solver (to 1e-12 of the target's size) and the optimality conditions."""
    from scipy.optimize import nnls

    rng = np.random.default_rng(7)
    at_bound = 0
    for _ in range(300):
        n = int(rng.integers(2, 6))
        points = list(zip(10 ** rng.uniform(-1, 3, n), 10 ** rng.uniform(0, 3, n), strict=True))
        D, y = _weighted(points)
        x = nnls_two(D, y)
        _, rnorm = nnls(D, y)
        assert np.linalg.norm(D @ np.array(x) - y) <= rnorm + 1e-12 * np.linalg.norm(y)
        _kkt(D, y, x)
        at_bound += min(x) == 0
    assert 30 < at_bound < 270  # both kinds of solution were tried


def test_nnls_two_singular_tables_are_pure_shot_noise() -> None:
    """Points at one radiance (the columns 1/σ² and L/σ² parallel): every split of the fit is as good, and the
    solver takes the one-point rule's, a = 0 and b the weighted least-squares slope (by hand: Σ(L/σ²)·1 / Σ(L/σ²)²);
    a zero design gives zero; a repeated point is the one point's model."""
    points = [(50.0, 100.0), (50.0, 80.0), (50.0, 120.0)]
    D, y = _weighted(points)
    a, b = nnls_two(D, y)
    col = D[:, 1]
    assert a == 0.0 and b == pytest.approx(col.sum() / (col @ col), rel=1e-14)
    assert nnls_two(np.zeros((3, 2)), np.ones(3)) == (0.0, 0.0)
    twice = fit_noise_model([(6.0, 50.0), (6.0, 50.0)], 30.0)
    once = fit_noise_model([(6.0, 50.0)], 30.0)
    assert twice.a == 0.0 and twice.b == pytest.approx(once.b, rel=1e-14)


def test_noise_model_of_table1_matches_scipy() -> None:
    """Every Sentinel-2 band's (a, b) against scipy's solver on the same weighted problem (it was the solver before)."""
    from scipy.optimize import nnls

    for band in Sensor.sentinel2().bands:
        if len(band.snr_points) < 2:
            continue
        D, y = _weighted(list(band.snr_points))
        want, _ = nnls(D, y)
        np.testing.assert_allclose((band.noise.a, band.noise.b), want, rtol=1e-14)


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


@pytest.mark.parametrize("design, want", [
    ([[1.0, 0.0], [2.0, 0.0]], (1.0, 0.0)),  # the second column is zero: the first fits alone
    ([[1.0, -1.0], [2.0, -2.0]], (1.0, 0.0)),  # parallel, the second pointing away from the target
    ([[1.0, 1.0], [2.0, 2.0]], (0.0, 1.0)),  # parallel, both fit: the second alone (pure shot noise in the model)
])
def test_nnls_two_on_rank_one_designs(design, want) -> None:
    """Rank-1 designs against ``y = (1, 2)``, by hand: the fit reaches y exactly, with the column that can (before:
    (0, 0) for the first two, residual 2.24)."""
    x = nnls_two(np.array(design), np.array([1.0, 2.0]))
    np.testing.assert_allclose(x, want, rtol=1e-15, atol=1e-15)
