"""The resampling kernel reading a cube's native samples and interpolating them onto the grid itself
(:class:`s2cl.forward.grid_interpolation.GridInterpolation`), against a float64 oracle written apart from it:
``numpy.interp`` of each pixel onto the grid, then the float64 twin of the atmosphere and the SRFs
(:mod:`s2cl.reference.forward`).

Tolerances (relative to each band's largest value): the kernel's float32 interpolation rounds each grid value once
more than the oracle's (a few ulp, 1e-7 relative) before the sums that ``tests/test_resample_kernel.py`` bounds at
2e-6; observed about 2e-7. float64: 1e-12, as there.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from s2cl.app.chain_parts import scene_simulator
from s2cl.app.image_simulation import scene_cube
from s2cl.errors import InputError
from s2cl.forward.grid_interpolation import GridInterpolation
from s2cl.forward.resample import ResamplePlan, Resampler
from s2cl.grid import SpectralGrid
from s2cl.reference import forward as ref
from s2cl.sensor.sensor import Sensor
from s2cl.sensor.srf import point_weights

RTOL = {"float32": 2e-6, "float64": 1e-12}
#: EnMAP-like bands: VNIR then SWIR spacing, the water windows left out (a bad-band gap each), unevenly spaced
_VNIR, _SWIR = np.linspace(418.42, 993.05, 91), np.linspace(1001.3, 2445.53, 133)
NATIVE = np.concatenate([_VNIR, _SWIR[~(((_SWIR > 1340) & (_SWIR < 1445)) | ((_SWIR > 1790) & (_SWIR < 1960)))]])
GRID = SpectralGrid(419, 2445, 1)


class _Terms:
    def __init__(self, n: int, rng: np.random.Generator):
        self.path_radiance = rng.uniform(1, 60, n)
        self.ground_term = rng.uniform(10, 150, n)
        self.spherical_albedo = rng.uniform(0.02, 0.3, n)


def _plan(grid: SpectralGrid, weights: list | None = None) -> ResamplePlan:
    w = weights or [b.weights(grid) for b in Sensor.sentinel2().bands]
    return ResamplePlan(tuple(f"b{k}" for k in range(len(w))), tuple(w), grid.size)


def _oracle(samples: np.ndarray, native: np.ndarray, grid: SpectralGrid, plan: ResamplePlan,
            terms: _Terms | None) -> np.ndarray:
    """float64: each pixel through numpy.interp onto the grid, then the atmosphere per wavelength and the SRFs."""
    on = np.stack([np.interp(grid.wavelengths, native, row) for row in np.asarray(samples, np.float64)])
    if terms is not None:
        on = ref.toa_radiance(on, terms.path_radiance, terms.ground_term, terms.spherical_albedo)
    return ref.resample(on, plan.weights)


def _check(out: np.ndarray, expected: np.ndarray, real_t: str) -> None:
    assert np.isfinite(out).all()
    scale = np.abs(expected).max(axis=1, keepdims=True) + 1e-300
    err = np.abs(out.astype(np.float64) - expected) / scale
    assert err.max() <= RTOL[real_t], f"max relative error {err.max():.3g}"


def _reflectance(n: int, bands: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.clip(0.3 + np.cumsum(rng.normal(0, 0.02, (n, bands)), axis=1), 0.0, 0.9)


def test_the_table_is_numpy_interp_by_hand() -> None:
    """Nodes 400, 410, 430: a grid wavelength on a node takes that node alone (upper == lower, fraction 0), one
    between takes its two neighbours, one outside the nodes the end node (clamped, as numpy.interp)."""
    t = GridInterpolation.of(np.array([400.0, 410.0, 430.0]), np.array([395.0, 400.0, 405.0, 410.0, 425.0, 430.0,
                                                                       431.0]))
    assert t.lower.tolist() == [0, 0, 0, 1, 1, 2, 2]
    assert t.upper.tolist() == [0, 0, 1, 1, 2, 2, 2]
    np.testing.assert_array_equal(t.fraction, [0.0, 0.0, 0.5, 0.0, 0.75, 0.0, 0.0])
    assert t.n_native == 3 and t.n_grid == 7


@pytest.mark.parametrize(("width", "rows"), [(None, None), (4, 1), (8, 4), (16, 8), (4, 16)])
def test_atmosphere_over_native_samples_matches_the_oracle(rt, real_t: str, width: int | None,
                                                           rows: int | None) -> None:
    """EnMAP-like bands (uneven spacing, two bad-band gaps) onto a 1 nm grid, the atmosphere per grid wavelength,
    at every vector width and rows per work-item, with a pixel count that leaves a partial work-item."""
    rng = np.random.default_rng(1)
    terms, plan = _Terms(GRID.size, rng), _plan(GRID)
    rho = _reflectance(37, NATIVE.size, 2)
    r = Resampler(rt, plan, real_t, atmosphere=terms, vector_width=width, rows_per_item=rows,
                  interpolation=GridInterpolation.covering(NATIVE, GRID))
    _check(r(rho.astype(real_t)), _oracle(rho.astype(real_t), NATIVE, GRID, plan, terms), real_t)


def test_radiance_over_native_samples_matches_the_oracle(rt, real_t: str) -> None:
    """No atmosphere (a radiance cube): the interpolated grid values straight into the SRFs; chunked launches."""
    plan = _plan(GRID)
    radiance = 40.0 + 100.0 * _reflectance(301, NATIVE.size, 3)
    r = Resampler(rt, plan, real_t, interpolation=GridInterpolation.covering(NATIVE, GRID))
    _check(r(radiance, chunk_pixels=64), _oracle(radiance.astype(real_t), NATIVE, GRID, plan, None), real_t)


def test_a_product_covering_part_of_the_grid(rt, real_t: str) -> None:
    """Samples from 500 to 2000 nm on a grid of 400-2500 nm: the chain refuses it in one line (it never
    extrapolates); the table alone clamps the grid's ends to the end samples, as numpy.interp does."""
    native = np.linspace(500.0, 2000.0, 120)
    grid = SpectralGrid(400, 2500, 1)
    with pytest.raises(InputError, match="spectra cover 500–2000 nm but the grid needs 400–2500 nm"):
        GridInterpolation.covering(native, grid, source="cube.nc")
    rng = np.random.default_rng(4)
    terms, plan = _Terms(grid.size, rng), _plan(grid)
    rho = _reflectance(19, native.size, 5)
    r = Resampler(rt, plan, real_t, atmosphere=terms, interpolation=GridInterpolation.of(native, grid.wavelengths))
    _check(r(rho), _oracle(rho.astype(real_t), native, grid, plan, terms), real_t)


def test_a_grid_wavelength_on_a_node_never_reads_the_next_one(rt, real_t: str) -> None:
    """The grid ends on a native wavelength (fraction exactly 0) whose next sample is inf: point bands there and
    just below take the node's value, finite; a kernel reading the next sample would give 0 · inf = NaN."""
    native = np.array([400.0, 410.0, 420.0, 430.0])
    grid = SpectralGrid(400, 420, 1)  # ends on the node at 420 nm; the sample at 430 nm lies beyond it
    plan = _plan(grid, [point_weights(grid, c) for c in (420.0, 417.0, 405.0)])
    samples = np.array([[0.1, 0.3, 0.5, np.inf], [0.2, 0.2, 0.6, np.inf]])
    table = GridInterpolation.of(native, grid.wavelengths)
    assert table.fraction[-1] == 0.0 and table.upper[-1] == table.lower[-1] == 2
    for width in (4, 8, 16):
        out = Resampler(rt, plan, real_t, vector_width=width, interpolation=table)(samples)
        _check(out, _oracle(samples[:, :3], native[:3], grid, plan, None), real_t)


def test_wavelengths_out_of_order_are_refused_in_one_line() -> None:
    """The table needs increasing wavelengths: the readers sort a product's bands (PRISMA's come in decreasing
    wavelength, below); a cube given out of order is refused naming the position."""
    with pytest.raises(InputError, match=r"cube\.nc: wavelength: must be strictly increasing; position 1"):
        GridInterpolation.covering(NATIVE[::-1], GRID, source="cube.nc")


def test_spectra_of_the_wrong_width_are_refused(rt) -> None:
    r = Resampler(rt, _plan(GRID), interpolation=GridInterpolation.covering(NATIVE, GRID))
    with pytest.raises(InputError, match=f"reads {NATIVE.size} values per spectrum"):
        r(np.zeros((3, GRID.size)))


@pytest.mark.parametrize("name", ["enmap", "prisma"])
def test_a_product_through_the_chain_matches_the_oracle(rt, real_t: str, tmp_path: Path, name: str) -> None:
    """A product in its shipped layout (EnMAP: bad bands filled with no data, an empty corner; PRISMA: two
    detectors stored in decreasing wavelength, overlapping): the scene's cube gives its rows at the product's
    wavelengths, NODATA pixels zero, and the chain's kernel puts them on the grid. The oracle starts from the
    fixture's own truth (the good bands sorted by wavelength by hand, no-data pixels zeroed) through numpy.interp."""
    pytest.importorskip("rasterio", reason="the geo extra reads GeoTIFF")
    sys.path.insert(0, str(Path(__file__).parent))
    import product_fixtures as pf

    from s2cl.app.product_scene import resolve_product_scene
    from s2cl.scene.scene import Scene
    from s2cl.scene.terms import scene_atmosphere

    writer = {"enmap": pf.write_enmap, "prisma": pf.write_prisma}[name]
    path, truth = writer(tmp_path)
    scene = Scene.from_dict({"scene": {"name": "p"}, "compute": {"precision": real_t},
                             "surface": {"cube": path.name, "quantity": "reflectance", "gsd_m": 10.0},
                             "effects": {"atmosphere": True}}, base_dir=tmp_path)
    cube = scene_cube(scene)
    scene = resolve_product_scene(scene)[0]  # the grid taken from the product's coverage
    assert cube.interpolation is not None
    order = [i for i in np.argsort(truth.wavelengths_nm, kind="stable") if truth.good[i]]
    kept = [i for i in order if not (name == "prisma" and _prisma_overlap(truth, i))]
    stored = truth.stored[:, :, kept].reshape(-1, len(kept))
    native = truth.wavelengths_nm[kept]
    # as the file states them: EnMAP's XML to 3 decimals, PRISMA's attributes in float32
    native = np.round(native, 3) if name == "enmap" else native.astype(np.float32).astype(np.float64)
    empty = ~np.isfinite(stored).all(axis=1)
    assert empty.any()
    block, nodata = cube.block(0, cube.rows)
    assert block.shape == (cube.rows * cube.cols, native.size) and np.array_equal(nodata, empty)
    assert (block[empty] == 0).all()  # NODATA pixels zero; the others the stored values (read as float32)
    np.testing.assert_allclose(block[~empty], stored[~empty], rtol=2e-7)
    atmosphere = scene_atmosphere(scene)
    sim = scene_simulator(rt, scene, atmosphere=atmosphere, interpolation=cube.interpolation)
    out = sim.band_radiance(block)
    expected = _oracle(block, native, scene.grid, sim.plan, atmosphere)  # the values read, as the kernel got them
    _check(out, expected, real_t)


def _prisma_overlap(truth, i: int) -> bool:
    """Whether PRISMA band ``i`` (file order: VNIR then SWIR) is a VNIR band the reader leaves out for the SWIR
    detector (at or above the first kept SWIR wavelength)."""
    n_vnir = 66
    swir = truth.wavelengths_nm[n_vnir:][truth.good[n_vnir:]]
    return i < n_vnir and truth.wavelengths_nm[i] >= swir.min()
