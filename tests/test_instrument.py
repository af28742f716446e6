"""Image effects on image cubes ([effects] psf, coregistration, smile, nonuniformity): per-band MTF,
co-registration shift, spectral smile,
detector non-uniformity — each against its float64 twin or its defining property, and absent when off."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

from s2cl.app.chain_parts import chain_parts, scene_instrument, scene_simulator
from s2cl.app.image_simulation import scene_cube, simulate_image
from s2cl.errors import InputError
from s2cl.forward import cube as cube_module
from s2cl.forward import instrument as inst
from s2cl.forward.cube import aggregate
from s2cl.forward.instrument import (
    Instrument,
    Smile,
    gaussian_sigma,
    lagrange,
    smile_twin,
    spatial_response,
    spatial_twin,
)
from s2cl.forward.resample import Resampler
from s2cl.grid import DEFAULT_GRID
from s2cl.scene.instrument_schema import BOX_MTF_NYQUIST
from s2cl.scene.scene import Scene
from s2cl.status import PixelFlag


def _cube(rows: int = 24, cols: int = 24, seed: int = 0) -> np.ndarray:
    """Radiance cube: fields of two spectral shapes with sharp edges (so smile and shifts show)."""
    rng = np.random.default_rng(seed)
    wl = DEFAULT_GRID.wavelengths
    veg = 80.0 / (1.0 + np.exp(-(wl - 715.0) / 12.0)) + 20.0 * np.exp(-(((wl - 550) / 40) ** 2))
    soil = 30.0 + 0.02 * (wl - 400.0)
    a = rng.uniform(0.2, 1.0, (rows, cols, 1))
    return (a * np.where(rng.random((rows, cols, 1)) < 0.5, veg, soil)).astype(np.float32)


#: the former [instrument] switches and keys (as the tests below give them) → the [effects] key and its settings
_HOME = {"mtf": ("psf", {"mtf_nyquist": "mtf_nyquist", "mtf_nyquist_bands": "bands"}),
         "coregistration": ("coregistration", {"coregistration_px": "px", "coregistration_shifts": "shifts"}),
         "smile": ("smile", {"smile_centre_nm": "centre_nm", "smile_width_pct": "width_pct"}),
         "nonuniformity": ("nonuniformity", {k: k for k in ("gain_pct", "offset_pct", "equalised",
                                                          "residual_gain_pct", "residual_offset_pct")})}


def _effects(instrument: dict) -> dict:
    """[effects] keys of the image effects switched on in ``instrument`` (written by hand, in the old names)."""
    out = {}
    for switch, (name, keys) in _HOME.items():
        if instrument.get(switch):
            out[name] = {new: instrument[old] for old, new in keys.items() if old in instrument} or True
    return out


def _scene(instrument: dict | None = None, **kw) -> Scene:
    effects = {"seed": 3, **_effects(instrument or {}), **kw.pop("effects", {})}
    spatial = kw.pop("spatial", None)
    if spatial:
        effects["psf"] = {"fwhm": spatial.get("psf_fwhm", 1.0)}
    data = {"scene": {"name": "cube"}, "surface": {"cube": "cube.nc", "gsd_m": 10.0}, "effects": effects, **kw}
    return Scene.from_dict(data)


# -- MTF ---------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("mtf", [0.15, 0.3, 0.5])
@pytest.mark.parametrize(("axis", "tol"), [(1, 2e-3), (0, 1e-2)])
def test_mtf_at_nyquist_is_the_given_value(mtf: float, axis: int, tol: float) -> None:
    """A sine at the band's Nyquist frequency, phase-aligned with the band pixels: after the band's Gaussian and
    the box average its amplitude is the MTF (input grid 20× finer than the band's). Across the image (axis 1, FFT)
    to 2e-3, along it (axis 0, the finite filter) to 1e-2."""
    f = 20
    n = 40 * f
    x = np.arange(n) + 0.5
    image = np.tile(np.cos(math.pi * x / f - math.pi / 2), (8 * f, 1))
    if axis == 0:
        image = image.T.copy()
    sigma = gaussian_sigma(mtf) * f
    out = aggregate(spatial_response(image, sigma, 0.0, 0.0), f)
    inner = out[2:-2, 4:-4] if axis == 1 else out[4:-4, 2:-2]
    # the sampled box of f fine pixels has MTF sin(π/2)/(f·sin(π/(2f))) instead of 2/π: compare with that system
    box = 1.0 / (f * math.sin(math.pi / (2 * f)))
    assert np.abs(inner).max() == pytest.approx(mtf / BOX_MTF_NYQUIST * box, rel=tol)


def test_gaussian_sigma_refuses_mtf_above_the_box() -> None:
    with pytest.raises(ValueError):
        gaussian_sigma(0.7)
    with pytest.raises(InputError, match=r"effects\.psf\.mtf_nyquist"):
        _scene({"mtf": True, "mtf_nyquist": 0.7})


def test_fft_blur_matches_spatial_convolution_twin() -> None:
    """The FFT twin against scipy's direct Gaussian convolution with mirrored borders; the production filter (FFT
    across, finite filter along) against the twin."""
    img = _cube(40, 50)[:, :, 300].astype(np.float64)
    twin = spatial_twin(img, 2.3, 0.0, 0.0)
    direct = gaussian_filter(img, 2.3, mode="reflect", truncate=8.0)
    assert np.max(np.abs(twin - direct)) < 1e-4 * np.abs(direct).max()
    assert np.max(np.abs(spatial_response(img, 2.3, 0.0, 0.0) - twin)) < 1e-4 * np.abs(twin).max()


@pytest.mark.parametrize(("sigma", "dx", "dy", "smooth", "tol"), [
    (0.8, 0.3, -0.45, 0.0, 1e-2), (3.0, 1.2, 0.7, 0.0, 1e-3), (0.0, 0.0, 0.5, 1.5, 1e-2)])
def test_spatial_step_against_its_fft_twin(sigma, dx, dy, smooth, tol) -> None:
    """Relative to the image's range, on a pixel-scale random image (the hardest case for the finite filter's
    truncation): blur and shift together, a wide PSF; and a pure half-pixel shift of the image smoothed first (a
    sub-pixel shift of pixel-scale noise is ill-defined: two interpolators differ by some 10 % there)."""
    img = _cube(60, 60)[:, :, 700].astype(np.float64)
    if smooth:
        img = gaussian_filter(img, smooth, mode="reflect")
    err = np.abs(spatial_response(img, sigma, dx, dy) - spatial_twin(img, sigma, dx, dy))[15:-15, 15:-15]
    assert err.max() < tol * np.ptp(img)


# -- co-registration -----------------------------------------------------------------------------------------

def test_integer_shift_is_a_roll_and_fraction_moves_a_sine() -> None:
    img = _cube(30, 30)[:, :, 500].astype(np.float64)
    out = spatial_response(img, 0.0, 3.0, -2.0)
    assert np.allclose(out[:-2, 3:], img[2:, :-3], atol=1e-9)  # out(y, x) = img(y - dy, x - dx)
    # a band-limited sine moved by 0.37 pixels: exact (the twin is the analytic sine)
    x = np.arange(64.0)
    sine = np.tile(np.sin(2 * math.pi * x / 16), (8, 1))
    moved = spatial_response(sine, 0.0, 0.37, 0.0)
    assert np.allclose(moved[:, 16:48], np.tile(np.sin(2 * math.pi * (x - 0.37) / 16), (8, 1))[:, 16:48],
                       atol=2e-3)
    down = spatial_response(sine.T.copy(), 0.0, 0.0, 0.37)  # along columns: the finite filter
    assert np.allclose(down[16:48, :], np.tile(np.sin(2 * math.pi * (x - 0.37) / 16), (8, 1)).T[16:48, :],
                       atol=2e-3)


def test_a_nan_pixel_reaches_exactly_the_filters_support() -> None:
    """σ = 1 px, shift (2, -0.7) px: the filter reaches R = ⌈|d| + 4σ + taper + 1⌉ - 1 pixels along each axis (the
    taper, round(8·exp(-π²σ²/2)) = round(0.058), is 0): 6 along rows, 5 along columns, by hand. A NaN pixel makes
    NaN exactly that rectangle around it; every other pixel is the hole-free image's, bit for bit. Changing the
    pixel's value instead changes only pixels inside the rectangle, out to its edge on the side the image moves to."""
    img = _cube(30, 30)[:, :, 400].astype(np.float64)
    holed = img.copy()
    holed[10, 12] = np.nan
    out = spatial_response(holed, 1.0, 2.0, -0.7)
    ref = spatial_response(img, 1.0, 2.0, -0.7)
    rect = np.zeros(img.shape, bool)
    rect[10 - 5 : 10 + 5 + 1, 12 - 6 : 12 + 6 + 1] = True
    assert np.array_equal(np.isnan(out), rect)
    assert np.array_equal(out[~rect], ref[~rect])
    other = img.copy()
    other[10, 12] += 50.0
    changed = spatial_response(other, 1.0, 2.0, -0.7) != ref
    assert not (changed & ~rect).any()
    rows, cols = np.nonzero(changed)
    assert rows.min() == 10 - 5 and cols.max() == 12 + 6  # content moves up (dy < 0) and right (dx > 0)


def test_instrument_passes_each_band_its_own_psf_and_shift_in_input_pixels() -> None:
    """What :meth:`Instrument.spatial` hands the filter, by hand: a 20 m band over a 10 m cube (2 input pixels per
    band pixel) with its own MTF at Nyquist (0.3) and shift; a 10 m band with the scene's MTF (0.15)."""
    scene = _scene({"mtf": True, "mtf_nyquist_bands": {"B5": 0.3}, "coregistration": True,
                    "coregistration_shifts": {"B5": [0.4, -0.25], "B4": [0.0, 0.5]}})
    a = scene_instrument(scene)
    b5, b4 = a.band_names.index("B5"), a.band_names.index("B4")
    sigma_b5 = math.sqrt(-2.0 * math.log(0.3 * math.pi / 2.0)) / math.pi  # exp(-2π²σ²/4)·2/π = 0.3
    sigma_b4 = math.sqrt(-2.0 * math.log(0.15 * math.pi / 2.0)) / math.pi
    assert a.psf_sigma(b5) == pytest.approx(sigma_b5, rel=1e-12) and a.band_attrs(b5)["mtf_nyquist"] == 0.3
    img = _cube(40, 40)[:, :, 600].astype(np.float64)
    np.testing.assert_array_equal(a.spatial(img, b5, 2), spatial_response(img, 2 * sigma_b5, 0.8, -0.5))
    np.testing.assert_array_equal(a.spatial(img.astype(np.float32), b4, 1),
                                  spatial_response(img, sigma_b4, 0.0, 0.5).astype(np.float32))


def test_shifts_from_seed_have_the_given_magnitude() -> None:
    a = scene_instrument(_scene({"coregistration": True}))
    shifts = [a.shift(k) for k in range(len(a.band_names))]
    assert all(math.hypot(*s) == pytest.approx(0.15) for s in shifts)
    assert len({round(s[0], 9) for s in shifts}) == len(shifts)  # a direction per band
    assert shifts == [scene_instrument(_scene({"coregistration": True})).shift(k) for k in range(len(shifts))]
    other = scene_instrument(_scene({"coregistration": True}, effects={"seed": 4}))
    assert other.shift(0) != shifts[0]
    given = scene_instrument(_scene({"coregistration": True, "coregistration_shifts": {"B5": [0.1, -0.2]}}))
    assert given.shift(given.band_names.index("B5")) == (0.1, -0.2)


def test_shifted_band_in_the_cube(rt) -> None:
    """B4 (10 m) shifted by one band pixel in x, B5 (20 m: 2 input pixels per band pixel) by one band pixel in x
    and -1 in y, B1 (60 m: 6 input pixels) by -1 in x: each radiance image is the ideal one moved by whole band
    pixels, ``moved(y, x) = ideal(y - dy, x - dx)``, away from the borders the filter mirrors."""
    cube = _cube()
    off = {"noise": False, "quantise": False, "calibrate": False}
    ideal = simulate_image(rt, _scene(effects=off), cube)
    moved = simulate_image(rt, _scene({"coregistration": True, "coregistration_shifts": {
        "B4": [1.0, 0.0], "B5": [1.0, -1.0], "B1": [-1.0, 0.0]}}, effects=off), cube)
    assert moved["radiance_B4"].attrs["shift_x_px"] == 1.0 and "shift_x_px" not in ideal["radiance_B4"].attrs
    a, b = ideal["radiance_B4"].values, moved["radiance_B4"].values
    assert np.allclose(b[:, 1:], a[:, :-1], rtol=1e-5)
    a, b = ideal["radiance_B5"].values, moved["radiance_B5"].values  # 12 × 12
    assert np.allclose(b[:-1, 1:], a[1:, :-1], rtol=1e-5)
    a, b = ideal["radiance_B1"].values, moved["radiance_B1"].values  # 4 × 4
    assert np.allclose(b[:, :-1], a[:, 1:], rtol=1e-5)
    # bands without a given shift keep their seeded one (0.15 px): changed, but not by a whole pixel
    assert not np.allclose(moved["radiance_B3"].values, ideal["radiance_B3"].values, rtol=1e-4)


# -- smile ---------------------------------------------------------------------------------------------------

def test_smile_per_column_by_hand() -> None:
    """Column positions x = 2 (i + 1/2) / cols - 1 (4 columns: -0.75, -0.25, 0.25, 0.75), Δλ = 1 + 0·x + 2x² nm,
    width change 5·x %."""
    scene = _scene({"smile": True, "smile_centre_nm": [1.0, 0.0, 2.0], "smile_width_pct": [0.0, 5.0]})
    smile = Smile.of(scene_instrument(scene).smile_spec, 4)
    np.testing.assert_allclose(smile.shift_nm, [2.125, 1.125, 1.125, 2.125], rtol=1e-15)
    np.testing.assert_allclose(smile.width_factor, [0.9625, 0.9875, 1.0125, 1.0375], rtol=1e-15)


@pytest.mark.parametrize("tabulated", [False, True])
def test_moved_weights_move_and_stretch_the_srf(tabulated: bool) -> None:
    """A band's SRF moved by Δ nm and stretched by w about its centre c: its centroid goes from m to c + (m - c)·w
    + Δ and its standard deviation from s to w·s (moments of the weights on the 1 nm grid), for B4's model SRF and
    for a lopsided tabulated one."""
    from dataclasses import replace

    from s2cl.sensor.srf import TabulatedResponse

    band = _scene().sensor.band("B4")
    if tabulated:
        wl = np.arange(610.0, 720.5, 0.5)
        band = replace(band, tabulated=TabulatedResponse(wl, np.exp(-(((wl - 660.0) / 12.0) ** 2))
                                                         * (1.0 + (wl - 610.0) / 40.0), "test"))

    def moments(w) -> tuple[float, float]:
        wl, v = DEFAULT_GRID.wavelengths[w.start : w.stop], w.weights
        m = float((v * wl).sum() / v.sum())
        return m, float(np.sqrt((v * (wl - m) ** 2).sum() / v.sum()))

    m, sd = moments(inst.moved_weights(band, DEFAULT_GRID, 0.0, 1.0, 1.0))
    c = band.centre_nm
    for shift, width in ((3.0, 1.0), (0.0, 1.2), (-2.5, 0.9)):
        m2, sd2 = moments(inst.moved_weights(band, DEFAULT_GRID, shift, width, 1.0))
        assert m2 == pytest.approx(c + (m - c) * width + shift, abs=1e-3), (shift, width)
        assert sd2 == pytest.approx(width * sd, rel=1e-3), (shift, width)


def test_lagrange_reproduces_a_quadratic() -> None:
    nodes = np.array([-1.0, 0.2, 1.5])
    x = np.linspace(-1, 1.5, 11)
    basis = lagrange(nodes, x)
    assert np.allclose(basis.sum(axis=0), 1.0)
    assert np.allclose((3 * nodes**2 - nodes + 2) @ basis, 3 * x**2 - x + 2)


@pytest.mark.parametrize(("spec", "tol"), [
    ({"smile_centre_nm": [0.0, 0.0, 1.0]}, 1e-6),
    ({"smile_centre_nm": [0.5, -2.0, 1.5], "smile_width_pct": [0.0, 5.0]}, 1e-4)])
def test_smile_against_per_column_twin(rt, spec, tol) -> None:
    """Node interpolation on the device against each column's own SRF integral in float64: the default smile
    (1 nm) to 1e-6, a 5 nm smile with a 5 % width change to 1e-4 (the SRF support's cut-off makes the band value a
    slightly rough function of the shift), where the smile itself changes the bands by 10-40 %."""
    scene = _scene({"smile": True, **spec}, compute={"precision": "float64"})
    cube = _cube(6, 40)
    prepared = scene_cube(scene, cube, None)
    parts = chain_parts(scene, atmosphere=None)
    ours = inst.smile_radiance(rt, parts, prepared.spectra, 6, 40)
    twin = smile_twin(parts, prepared.spectra, 6, 40)
    nominal = scene_simulator(rt, scene).band_radiance(prepared.spectra).reshape(twin.shape)
    err = np.abs(ours - twin) / np.abs(twin)
    assert err.max() < tol
    assert np.max(np.abs(nominal - twin) / np.abs(twin)) > 1e3 * tol  # the smile itself is far above that


def test_smile_in_the_cube_against_per_column_twin(rt) -> None:
    """The cube path (node bands per block of 2 rows, combined per column, then the 20 m box average) against each
    column's own SRF integral in float64 (:func:`smile_twin`), box-averaged by hand for B5: within 1e-6."""
    scene = _scene({"smile": True}, sensor={"bands": ["B4", "B5"]}, compute={"precision": "float64"},
                   effects={"noise": False, "quantise": False, "calibrate": False})
    cube = _cube(6, 40)
    ds = simulate_image(rt, scene, cube, block_rows=2)
    twin = smile_twin(chain_parts(scene), scene_cube(scene, cube, None).spectra, 6, 40)
    np.testing.assert_allclose(ds["radiance_B4"].values, twin[0], rtol=1e-6)
    np.testing.assert_allclose(ds["radiance_B5"].values, twin[1].reshape(3, 2, 20, 2).mean(axis=(1, 3)), rtol=1e-6)


def test_smile_is_absent_from_the_kernel_when_off(rt, monkeypatch) -> None:
    """Off: the cube path builds only the nominal resampling kernel (no node band in its source); on: the node
    bands are in the rendered source."""
    sources: list[str] = []
    original = Resampler.__init__

    def spy(self, *a, **k):
        original(self, *a, **k)
        sources.append(self.source)

    monkeypatch.setattr(Resampler, "__init__", spy)
    cube = _cube(12, 12)
    simulate_image(rt, _scene(), cube)
    assert sources and not any("smile" in s for s in sources)
    sources.clear()
    simulate_image(rt, _scene({"smile": True}), cube)
    assert any("B4~smile3" in s for s in sources)
    smile = Smile.of(scene_instrument(_scene({"smile": True})).smile_spec, 12)
    assert smile.node_grid()[0].size == inst.SMILE_NODES and smile.node_grid()[1].size == 1


# -- non-uniformity --------------------------------------------------------------------------------------------

def test_nonuniformity_columns_from_seed() -> None:
    scene = _scene({"nonuniformity": True, "residual_gain_pct": 1.0, "residual_offset_pct": 0.0})
    a = scene_instrument(scene)
    gain, offset = a.column_response(3, 5000)
    assert np.std(1.0 / gain - 1.0) == pytest.approx(0.01, rel=0.05)
    assert np.all(offset == 0.0)
    again = scene_instrument(_scene({"nonuniformity": True, "residual_gain_pct": 1.0, "residual_offset_pct": 0.0}))
    assert np.array_equal(again.column_response(3, 5000)[0], gain)
    assert not np.array_equal(a.column_response(4, 5000)[0], gain)
    raw = scene_instrument(_scene({"nonuniformity": True, "equalised": False, "gain_pct": 3.0}))
    g, o = raw.column_response(3, 5000)
    assert np.std(g) == pytest.approx(0.03, rel=0.05)
    assert np.std(o) == pytest.approx(0.005 * scene.sensor.bands[3].lref, rel=0.05)
    # equalised: (g L + o - (o + δ)) / (g (1 + ε)) written out (the twin)
    z = np.random.default_rng([3, inst._NU_TAG, 3]).standard_normal((4, 50))
    s = _scene({"nonuniformity": True})
    lref = s.sensor.bands[3].lref
    gr, orw = 1 + 0.02 * z[0], 0.005 * lref * z[1]
    eps, delta = 0.002 * z[2], 0.0005 * lref * z[3]
    L = np.linspace(10, 100, 50)
    expect = (gr * L + orw - (orw + delta)) / (gr * (1 + eps))
    gain, offset = scene_instrument(s).column_response(3, 50)
    assert np.allclose(gain * L + offset, expect, rtol=1e-12)


def test_nonuniformity_stripes_columns_in_the_cube(rt) -> None:
    """A flat cube: each band constant down its columns and striped across them, B5 (20 m, 12 columns over the 24 of
    the cube; band index 4) by its own equalised residual, written out from its draws: L · (g L + o - (o + δ)) /
    (g (1 + ε)) / L on the band's columns."""
    cube = np.broadcast_to(_cube(1, 1), (24, 24, DEFAULT_GRID.size)).copy()
    off = {"noise": False, "quantise": False, "calibrate": False}
    scene = _scene({"nonuniformity": True}, effects=off)
    ds = simulate_image(rt, scene, cube)
    ideal = simulate_image(rt, _scene(effects=off), cube)
    img = ds["radiance_B4"].values
    assert np.allclose(img, img[0:1, :], rtol=1e-6)  # constant down each column
    assert np.std(img[0]) / img[0].mean() > 5e-4  # but varying across
    assert ds.attrs["instrument"] == "nonuniformity"
    k = scene.sensor.band_names.index("B5")
    z = np.random.default_rng([3, inst._NU_TAG, k]).standard_normal((4, 12))
    lref = scene.sensor.bands[k].lref
    g, o, eps, delta = 1 + 0.02 * z[0], 0.005 * lref * z[1], 0.002 * z[2], 0.0005 * lref * z[3]
    flat = float(ideal["radiance_B5"].values[0, 0])
    expect = (g * flat + o - (o + delta)) / (g * (1 + eps))
    np.testing.assert_allclose(ds["radiance_B5"].values, np.broadcast_to(expect, (12, 12)), rtol=2e-6)


# -- off means skipped ---------------------------------------------------------------------------------------

def test_host_effects_are_skipped_when_off(rt, monkeypatch) -> None:
    """An ideal instrument runs no FFT and no column response: the functions are made to fail and the cube still
    simulates, to the same bits as before."""
    cube = _cube(12, 12)
    before = simulate_image(rt, _scene(), cube)

    def fail(*a, **k):
        raise AssertionError("instrument effect ran while off")

    monkeypatch.setattr(inst, "spatial_response", fail)
    monkeypatch.setattr(Instrument, "column_response", fail)
    monkeypatch.setattr(cube_module, "SmileResampler", fail)
    after = simulate_image(rt, _scene(), cube)
    assert after.attrs["instrument"] == "ideal"
    for name in before.data_vars:
        assert np.array_equal(before[name].values, after[name].values)


def test_instrument_scene_errors() -> None:
    with pytest.raises(InputError, match=r"effects\.psf\.bands.*unknown band"):
        _scene({"mtf": True, "mtf_nyquist_bands": {"B99": 0.2}})
    with pytest.raises(InputError, match=r"effects\.smile\.width_pct"):
        _scene({"smile": True, "smile_width_pct": [0.0, 0.0, -95.0]})
    with pytest.raises(InputError, match=r"effects\.resample"):
        _scene({"smile": True}, effects={"resample": False})
    with pytest.raises(InputError, match=r"effects\.coregistration\.shifts"):
        _scene({"coregistration": True, "coregistration_shifts": {"B4": [3.0, 0.0]}})
    legacy = {"scene": {"name": "cube"}, "surface": {"cube": "cube.nc", "gsd_m": 10.0}}
    with pytest.raises(InputError, match=r"spatial\.psf: instrument\.mtf and spatial\.psf both set a PSF"):
        Scene.from_dict({**legacy, "instrument": {"mtf": True}, "spatial": {"psf": "gaussian"}})
    with pytest.raises(InputError, match=r"effects\.psf and the deprecated"):
        Scene.from_dict({**legacy, "instrument": {"mtf": True}, "effects": {"psf": {"fwhm": 1.0}}})
    with pytest.raises(InputError, match=r"instrument\.mtf_nyquist: must be > 0"):
        Scene.from_dict({**legacy, "instrument": {"mtf": True, "mtf_nyquist": 0.7}})


# -- what each effect costs ------------------------------------------------------------------------------------

def test_effect_costs_on_a_small_fields_image(rt) -> None:
    """The instrument study's core on a 48 × 48 builtin:fields image: the ideal row has no effect and the noise
    floor against the truth; each effect differs from the ideal; the Cab map's error against the truth is scored
    for every row."""
    from s2cl.studies.instrument import cube_scene
    from s2cl.studies.instrument_costs import EFFECTS, analysis_score, effect_costs

    scene = cube_scene(Scene.load("study-instrument"), 48)
    rows = effect_costs(rt, scene, score=analysis_score(rt))
    assert [r.instrument for r in rows] == ["ideal", *EFFECTS]
    ideal = rows[0]
    assert all(v == 0.0 for v in ideal.rms_effect.values())
    assert 0.0 < ideal.as_dict()["rms_vs_truth_mean"] < 0.05
    for r in rows:
        assert 0.0 < r.score["cab_map_rms"] < 60.0 and 0.0 < r.score["fitted_fraction"] <= 1.0, r.instrument
    for r in rows[1:]:
        assert r.as_dict()["rms_effect_mean"] > 1e-5, r.instrument
        assert r.source and r.seconds > 0
        assert r.score["cab_map_rms"] != ideal.score["cab_map_rms"], r.instrument


def test_study_refuses_a_library_scene_and_resizing_a_file_cube(tmp_path) -> None:
    from s2cl.studies.instrument import cube_scene

    with pytest.raises(InputError, match=r"surface\.cube"):
        cube_scene(Scene.load("default"))
    with pytest.raises(InputError, match=r"study\.image_px"):
        cube_scene(_scene(), 48)


def test_effect_costs_ignores_the_scenes_switches(rt) -> None:
    """A scene with every effect on still gets an ideal row that is ideal, and its magnitudes are used."""
    from s2cl.studies.instrument_costs import effect_settings, with_effects

    s = _scene({"mtf": True, "mtf_nyquist": 0.3, "smile": True})
    ideal = with_effects(s, effect_settings(s))
    assert scene_instrument(ideal).describe() == "ideal" and ideal.spec.effects.psf.mtf_nyquist == 0.3
    only = with_effects(s, effect_settings(s, "psf"))
    assert scene_instrument(only).describe() == "psf" and scene_instrument(only).psf.mtf_nyquist == 0.3


# -- row blocks and no-data ----------------------------------------------------------------------------------

def test_row_blocks_match_the_whole_image(rt) -> None:
    """Every effect on, simulated in blocks of 12 rows (read with the halo of the spatial filters) and whole: the
    same variables, bit for bit, and the same band attributes."""
    cube = _cube(48, 48)
    scene = _scene({"mtf": True, "coregistration": True, "smile": True, "nonuniformity": True})
    whole = simulate_image(rt, scene, cube)
    blocks = simulate_image(rt, scene, cube, block_rows=12)
    assert set(whole.data_vars) == set(blocks.data_vars)
    for name in whole.data_vars:
        np.testing.assert_array_equal(whole[name].values, blocks[name].values, err_msg=name)
    for name in scene.sensor.band_names:
        assert whole[f"radiance_{name}"].attrs == blocks[f"radiance_{name}"].attrs


def test_row_blocks_with_a_shift_and_a_psf_read_both_reaches(rt) -> None:
    """Co-registration and a PSF given by its FWHM, in the one filter: a block is read with its reach (the 60 m
    bands: a shift of 1.5 band pixels along y, 9 input pixels, and a PSF of FWHM 1 band pixel, σ = 6 / 2.3548 =
    2.548 input pixels, taper round(8 exp(-π² σ² / 2)) = 0: ⌈9 + 4 σ + 0 + 1⌉ - 1 = 20 rows, ⌈4 σ + 1⌉ - 1 = 11
    columns): blocks of 6 rows give the whole image's bands bit for bit, and a NaN pixel's footprint is that
    reach."""
    from s2cl.forward.reach import band_groups, cube_halo

    scene = _scene({"coregistration": True, "coregistration_shifts": {"B1": [0.0, 1.5], "B9": [0.0, 1.5],
                                                                      "B10": [0.0, 1.5]}},
                   spatial={"psf": "gaussian", "psf_fwhm": 1.0})
    b1 = [scene.sensor.band_names.index(n) for n in ("B1", "B9", "B10")]
    inst = scene_instrument(scene)
    assert inst.reach(b1, 6) == (20, 11) and cube_halo(inst, band_groups(scene.sensor, 10.0)) == 20
    cube = _cube(72, 24)
    cube[40, 7, :] = np.nan
    whole = simulate_image(rt, scene, cube)
    blocks = simulate_image(rt, scene, cube, block_rows=6)
    for name in whole.data_vars:
        np.testing.assert_array_equal(whole[name].values, blocks[name].values, err_msg=name)
    # B1 (12 × 4): rows whose box [6i, 6i + 5] lies within 20 rows of row 40, columns within 11 of column 7
    expected = np.zeros((12, 4), bool)
    expected[[i for i in range(12) if 6 * i - 20 <= 40 <= 6 * i + 5 + 20], :] = True
    expected[:, [j for j in range(4) if not 6 * j - 11 <= 7 <= 6 * j + 5 + 11]] = False
    assert np.array_equal(np.isnan(whole["radiance_B1"].values), expected)


#: the no-data test's bands and their shifts [dx, dy] (band pixels)
HOLE_SHIFTS = {"B4": [0.6, -1.3], "B5": [-0.35, 0.8], "B1": [0.2, 0.45]}
#: their filters' reach (rows, cols) in input pixels, by hand: σ = √(-2 ln(0.15·π/2)) / π = 0.54123 band pixels
#: (the MTF at Nyquist 0.15), taper round(8·exp(-π²σ²/2)) for σ in input pixels, R = ⌈|d| + 4σ + taper + 1⌉ - 1.
#: B4 (1 input pixel per band pixel): σ 0.54123, taper 2; rows ⌈1.3 + 2.16491 + 3⌉ - 1 = 6, cols ⌈0.6 + 5.16491⌉ - 1
#: = 5. B5 (2): σ 1.08245, taper 0; rows ⌈1.6 + 4.32982 + 1⌉ - 1 = 6, cols ⌈0.7 + 5.32982⌉ - 1 = 6. B1 (6): σ
#: 3.24736, taper 0; rows ⌈2.7 + 12.98946 + 1⌉ - 1 = 16, cols ⌈1.2 + 13.98946⌉ - 1 = 15
HOLE_REACH = {"B4": (1, 6, 5), "B5": (2, 6, 6), "B1": (6, 16, 15)}


def _footprint(hole: tuple[int, int], shape: tuple[int, int], factor: int, rows: int, cols: int) -> np.ndarray:
    """Output pixels whose box, widened by ``rows`` / ``cols`` input pixels, holds the input pixel ``hole``."""
    out = np.zeros(shape, bool)
    for i in range(shape[0]):
        for j in range(shape[1]):
            out[i, j] = (i * factor - rows <= hole[0] <= (i + 1) * factor - 1 + rows
                         and j * factor - cols <= hole[1] <= (j + 1) * factor - 1 + cols)
    return out


def test_valid_pixels_near_a_hole_equal_the_hole_free_cube(rt) -> None:
    """The MTF and fractional shifts of a 10, a 20 and a 60 m band, noise on: a NaN input pixel makes NODATA exactly
    the output pixels whose box its filters reach (:data:`HOLE_REACH`, by hand), and every other pixel of every
    variable equals the hole-free cube's, bit for bit. Changing the pixel's spectrum instead changes only pixels
    inside that footprint, and reaches its edge on the side the image moves to."""
    scene = _scene({"mtf": True, "coregistration": True, "coregistration_shifts": HOLE_SHIFTS},
                   sensor={"bands": list(HOLE_SHIFTS)})
    cube = _cube(48, 48)
    holed, other = cube.copy(), cube.copy()
    holed[20, 20, :] = np.nan
    other[20, 20, :] *= 3.0
    ref, ds, changed = (simulate_image(rt, scene, c) for c in (cube, holed, other))
    for band, (factor, rows, cols) in HOLE_REACH.items():
        nodata = _footprint((20, 20), ds[f"radiance_{band}"].shape, factor, rows, cols)
        assert np.array_equal((ds[f"flags_{band}"].values & PixelFlag.NODATA) != 0, nodata), band
        assert ds[f"radiance_{band}"].attrs["nodata_pixels"] == nodata.sum() > 0
        for var in ("radiance", "noisy", "dn", "calibrated", "reflectance"):
            if f"{var}_{band}" in ds:
                np.testing.assert_array_equal(ds[f"{var}_{band}"].values[~nodata],
                                              ref[f"{var}_{band}"].values[~nodata], err_msg=f"{var}_{band}")
        moved = changed[f"radiance_{band}"].values != ref[f"radiance_{band}"].values
        assert moved.any() and not (moved & ~nodata).any(), band
    moved = np.nonzero(changed["radiance_B4"].values != ref["radiance_B4"].values)
    assert moved[0].min() == 20 - 6 and moved[1].max() == 20 + 5  # B4 moves up (dy < 0) and right (dx > 0)


# -- memory ------------------------------------------------------------------------------------------------------

#: the memory test's cube file: rows, columns, wavelengths (10 nm, float64) and the grid step (nm)
MEM_ROWS, MEM_COLS, MEM_WL, MEM_STEP = 96, 120, np.arange(400.0, 2501.0, 10.0), 5
#: rows its filters reach, by hand: the 60 m bands (6 input pixels per band pixel) with the MTF at Nyquist 0.15
#: (σ = 6 · 0.54123 = 3.24736, no taper) and a shift of 0.5 band pixels along y (3 input pixels): ⌈3 + 12.98946 +
#: 1⌉ - 1 = 16; the 20 m bands (σ 1.08245, seeded shifts of 0.3 input pixels at most) ⌈0.3 + 4.32982 + 1⌉ - 1 = 5,
#: the 10 m bands (σ 0.54123, taper 2, 0.15 at most) ⌈0.15 + 2.16491 + 3⌉ - 1 = 5
MEM_HALO = 16


def _memory_scene(tmp_path, name: str, rows: int, cols: int) -> Path:
    """An ENVI float64 cube of ``rows × cols`` pixels with one NaN pixel, and its scene file (MTF and
    co-registration on, the 60 m bands shifted by [0.1, 0.5] band pixels)."""
    data = np.memmap(tmp_path / f"{name}.bip", dtype="<f8", mode="w+", shape=(rows, cols, MEM_WL.size))
    shape = 0.05 + 0.4 / (1 + np.exp(-(MEM_WL - 715) / 12))
    for r in range(rows):
        data[r] = np.linspace(0.5, 1.3, cols)[:, None] * shape * (1.0 + 0.1 * math.sin(r))
    data[rows // 2, cols // 3, 7] = np.nan
    data.flush()
    del data
    (tmp_path / f"{name}.hdr").write_text(
        f"ENVI\nsamples = {cols}\nlines = {rows}\nbands = {MEM_WL.size}\nheader offset = 0\ndata type = 5\n"
        f"interleave = bip\nbyte order = 0\nwavelength = {{{', '.join(f'{w:g}' for w in MEM_WL)}}}\n")
    toml = tmp_path / f"{name}.toml"
    toml.write_text(f'[scene]\nname = "{name}"\n[grid]\nstep_nm = {MEM_STEP}\n[surface]\ncube = "{name}.hdr"\n'
                    'gsd_m = 10\nquantity = "reflectance"\n[effects]\natmosphere = true\nnoise = true\n'
                    'quantise = true\ncalibrate = true\npsf = true\n'
                    'coregistration = {shifts = {B1 = [0.1, 0.5], B9 = [0.1, 0.5], B10 = [0.1, 0.5]}}\n')
    return toml


#: bytes per input pixel of a row the memory test's cube is read with, by hand (float32 work, 13 bands, 211 samples
#: of the file, 421 of the 5 nm grid): the samples as read, mapped and copied as float64 (2 · 8 · 211 = 3,376), their
#: non-finite test (211), the resampling kernel's buffers, its native samples in and the 13 bands out in float32 (4 ·
#: (211 + 13) = 896), the NODATA mask (1); then the 10 m group (4 bands, 1 input pixel per band pixel), the largest:
#: the PSF's float64 work and its float32 copy (12), the band images before and after their stack (2 · 4 · 4 = 32),
#: the sense kernel's outputs held (noisy, dn, flags, calibrated: 4 · (4 + 2 + 1 + 4) = 44), and one launch's
#: arrays (the radiance made contiguous 16, a fetched output 16, the kernel's buffers: the outputs and the radiance,
#: 44 + 16) = 92: 4,664 bytes
MEM_PER_PIXEL = 4664
#: bytes of a block whatever its rows, by hand: the sense kernel's per-band values of the 10 m group's launch
#: (noise_a, noise_b, lmin, lmax, scale, gain: 6 · 4 bands · 4 bytes)
MEM_LAUNCH = 96
#: and where the host puts the spectra on the grid (the kernel not interpolating them): the spectra on the grid in
#: float64 (8 · 421 = 3,368) and the kernel reading 421 grid samples instead of 211 (4 · 210 = 840) more
MEM_PER_PIXEL_ON_GRID = MEM_PER_PIXEL + 3368 + 840


def test_a_cube_with_mtf_and_coregistration_streams_within_its_estimate(tmp_path, monkeypatch) -> None:
    """``s2cl simulate`` of a cube file with the MTF and co-registration under a --max-memory that leaves the bytes
    of 6 rows and their halo of 16 rows on each side (:data:`MEM_HALO`, by hand), at :data:`MEM_PER_PIXEL` bytes per
    input pixel read (by hand; the cube file holds nothing whole and there is no analysis): the memory rule picks
    blocks of 6 rows (a row less refuses the cube); the block reader holds at most 6 + 2 · 16 rows at once (measured
    on the reads), which the estimate's bytes cover within the limit; the traced peak stays inside what the limit
    leaves. Left out of the estimate, the halo would let blocks of 36 rows read up to 68."""
    import tracemalloc

    from s2cl.app.simulate_scene import cube_block_rows, simulate_scene
    from s2cl.errors import ResourceError
    from s2cl.forward.cube import SceneCube
    from s2cl.io.budget import BASELINE_BYTES, Budget

    toml = _memory_scene(tmp_path, "big", MEM_ROWS, MEM_COLS)
    small = _memory_scene(tmp_path, "small", 30, 30)
    sc = Scene.load(str(toml))
    assert (sc.grid.size, sc.sensor.size, sc.run.precision) == (421, 13, "float32")  # the figures' premises
    # the cube's 10 nm bands go into the resampling kernel as they are (it interpolates them onto the 5 nm grid):
    # no spectra on the grid are held
    per_row = MEM_COLS * MEM_PER_PIXEL
    fixed = BASELINE_BYTES + MEM_LAUNCH
    limit = math.ceil(fixed + (6 + 2 * MEM_HALO) * per_row)
    assert cube_block_rows(sc, Budget.of(str(limit)), MEM_ROWS, MEM_COLS, MEM_WL.size, True) == 6
    with pytest.raises(ResourceError, match=r"surface\.cube"):
        cube_block_rows(sc, Budget.of(str(limit - per_row)), MEM_ROWS, MEM_COLS, MEM_WL.size, True)
    with_grid = MEM_COLS * MEM_PER_PIXEL_ON_GRID  # a cube put on the grid on the host
    assert cube_block_rows(sc, Budget.of(str(math.ceil(fixed + (6 + 2 * MEM_HALO) * with_grid))), MEM_ROWS,
                           MEM_COLS, MEM_WL.size) == 6

    held: list[int] = []
    block = SceneCube.block

    def measured(self, start: int, stop: int) -> np.ndarray:
        held.append(stop - start)
        return block(self, start, stop)

    def traced(scene: Path, out: str, max_memory: str | None) -> tuple[int, dict]:
        tracemalloc.start()
        try:
            run = simulate_scene(scene, tmp_path / out, max_memory=max_memory)
            return tracemalloc.get_traced_memory()[1], json.loads((run.folder / "simulation.json").read_text())
        finally:
            tracemalloc.stop()

    traced(small, "warm", None)  # one-time costs: kernel builds
    base, _ = traced(small, "base", None)
    monkeypatch.setattr(SceneCube, "block", measured)
    peak, run = traced(toml, "streamed", str(limit))
    assert run["block_rows"] == 6 and run["attrs"]["nodata_input_pixels"] == 1
    assert max(held) == 6 + 2 * MEM_HALO
    assert fixed + max(held) * per_row <= limit
    assert peak - base < limit - BASELINE_BYTES, (peak, base, limit)
