"""The scene's analysis on an image cube's corrected band reflectance images (``s2cl simulate`` of a cube scene).

Common grid: the analysis bands are brought to the GSD of the coarsest of them by box averaging each band's
reflectance over the ``GSD_coarse / GSD_band`` square of its pixels (as an L2 processor makes its 20 m product
of the 10 m bands); a pixel with a non-finite reflectance in its box stays non-finite and its retrieval is
INVALID. The retrieval is :func:`s2cl.app.analysis.retrieve_pixels`, the one a library simulation runs.

Where the scene knows the truth (``builtin:fields``: the parameter maps of :mod:`s2cl.libraries.fields`), the
truth is averaged to the same grid (NaN where any input pixel of the box has none, e.g. a bare parcel's
chlorophyll); the index is calibrated to the parameter with the second-order polynomial
:func:`s2cl.retrieve.metrics.regression_metrics` fits, over the *pure* pixels (the box inside one parcel) whose
status enters the regression; the parameter map is that polynomial of the index, and the error map the map
minus the truth. Reported: the calibration's regression metrics (the library path's numbers), the map's RMS,
bias and R² over every pixel with an estimate and a truth (edges included), and the fit accounting.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import xarray as xr

from s2cl.app.analysis import PixelResults, retrieve_pixels
from s2cl.cl.runtime import Runtime
from s2cl.forward.cube import SceneCube, aggregate
from s2cl.retrieve.analysis import AnalysisSettings
from s2cl.retrieve.metrics import fit_accounting, poly2_fit, regression_metrics
from s2cl.scene.scene import Scene
from s2cl.status import FITTED, Status

#: CF flag attributes of the analysis status (:class:`s2cl.status.Status`)
STATUS_ATTRS = {"long_name": "retrieval status per pixel",
                "flag_values": np.array([s.value for s in Status], np.uint8),
                "flag_meanings": " ".join(s.name.lower() for s in Status)}
GRID_RULE = "box average of each analysis band's reflectance to the coarsest analysis band's GSD"


@dataclass(frozen=True)
class CommonGrid:
    """The analysis bands' reflectance ``(n_bands, ny, nx)`` on one grid of ``gsd_m``, with the OR of the
    radiometric flags of every input pixel of each box (None when the chain does not quantise)."""

    reflectance: np.ndarray
    flags: np.ndarray | None
    gsd_m: float

    @property
    def dims(self) -> tuple[str, str]:
        return f"y_{self.gsd_m:g}m", f"x_{self.gsd_m:g}m"


def common_grid(ds: xr.Dataset, scene: Scene, bands: list[str]) -> CommonGrid:
    """The analysis ``bands``' corrected reflectance of ``ds`` (:func:`s2cl.forward.cube.simulate_cube`) box-averaged
    to the coarsest band's GSD."""
    shapes = [scene.sensor.band(b) for b in bands]
    gsd = max(b.gsd_m for b in shapes)
    images, flags = [], None
    for b in shapes:
        factor = round(gsd / b.gsd_m)
        refl = ds[f"reflectance_{b.name}"].values
        images.append(aggregate(refl, factor))
        if f"flags_{b.name}" in ds:
            f = _box_or(ds[f"flags_{b.name}"].values, factor)
            flags = f if flags is None else flags | f
    ny = min(i.shape[0] for i in images)
    nx = min(i.shape[1] for i in images)
    stack = np.stack([i[:ny, :nx] for i in images])
    return CommonGrid(stack, None if flags is None else flags[:ny, :nx], gsd)


def _box_or(flags: np.ndarray, factor: int) -> np.ndarray:
    """Bitwise OR of ``factor × factor`` blocks (trailing partial blocks dropped, as :func:`aggregate` does)."""
    if factor == 1:
        return flags
    rows, cols = (flags.shape[0] // factor) * factor, (flags.shape[1] // factor) * factor
    blocks = flags[:rows, :cols].reshape(rows // factor, factor, cols // factor, factor)
    return np.bitwise_or.reduce(np.bitwise_or.reduce(blocks, axis=3), axis=1)


def truth_on_grid(truth: np.ndarray, factor: int, shape: tuple[int, int]) -> np.ndarray:
    """A truth map at the input GSD box-averaged by ``factor`` (NaN where any input pixel of the box has none)."""
    return aggregate(np.asarray(truth, dtype=np.float64), factor)[: shape[0], : shape[1]]


def pure_pixels(parcels: np.ndarray, factor: int, shape: tuple[int, int]) -> np.ndarray:
    """Pixels of the common grid whose box lies inside one parcel."""
    p = np.asarray(parcels, dtype=np.float64)
    same = aggregate(p, factor) == (_box_max(p, factor) if factor > 1 else p)
    return same[: shape[0], : shape[1]]


def _box_max(image: np.ndarray, factor: int) -> np.ndarray:
    rows, cols = (image.shape[0] // factor) * factor, (image.shape[1] // factor) * factor
    return image[:rows, :cols].reshape(rows // factor, factor, cols // factor, factor).max(axis=(1, 3))


def analyse_image(rt: Runtime, scene: Scene, ds: xr.Dataset, cube: SceneCube, bands: list[str],
                  settings: AnalysisSettings) -> dict[str, Any]:
    """Run the scene's analysis on the image ``ds``, add its map, status, flags (and, with a truth, the parameter,
    truth and error maps) to ``ds``; return the metrics and the fit accounting (``simulation.json``'s analysis)."""
    grid = common_grid(ds, scene, bands)
    nb, ny, nx = grid.reflectance.shape
    r = retrieve_pixels(rt, scene, bands, settings, grid.reflectance.reshape(nb, -1))
    dims = grid.dims
    ds["analysis_index"] = (dims, r.index.reshape(ny, nx).astype(np.float32),
                            {"long_name": f"{settings.kind} retrieval on {' '.join(bands)} (igrm: inflection "
                             "wavelength lp in nm; an index or formula: its value)", "analysis_kind": settings.kind})
    ds["analysis_status"] = (dims, r.status.reshape(ny, nx).astype(np.uint8), dict(STATUS_ATTRS))
    ds["analysis_bounds"] = (dims, r.bounds.reshape(ny, nx).astype(np.uint8),
                             {"long_name": "fit on a parameter bound (IGRM), 0: no"})
    if grid.flags is not None:
        ds["analysis_flags"] = (dims, grid.flags, {**_flag_attrs(ds, bands),
                                                   "long_name": "OR of the radiometric flags of the analysis "
                                                   "bands' pixels in each box"})
    ds.attrs.update(analysis_kind=settings.kind, analysis_bands=" ".join(bands), analysis_gsd_m=grid.gsd_m,
                    analysis_grid=GRID_RULE)
    out: dict[str, Any] = {"kind": settings.kind, "bands": bands, "map": "analysis_index", "gsd_m": grid.gsd_m,
                           "grid": GRID_RULE, "pixels": int(ny * nx), **_accounting(r)}
    truth = cube.truth.get(settings.parameter or "")
    if truth is not None and cube.parcels is not None:
        out.update(_against_truth(ds, scene, cube, r, truth, grid, settings))
    return out


def _flag_attrs(ds: xr.Dataset, bands: list[str]) -> dict[str, Any]:
    names = [n for n in ds.data_vars if str(n).startswith("flags_")]
    a = ds[names[0]].attrs if names else {}
    return {k: a[k] for k in ("flag_masks", "flag_meanings") if k in a}


def _accounting(r: PixelResults) -> dict[str, Any]:
    """How many pixels were fitted, invalid, degenerate, on a bound; the fractions per status."""
    status = r.status
    acc = {k: float(v[0]) for k, v in fit_accounting(status[None], r.bounds[None]).items()}
    fitted = np.isin(status, FITTED)
    return {**acc, "fitted_pixels": int(fitted.sum()), "invalid_pixels": int((status == Status.INVALID).sum()),
            "degenerate_pixels": int((status == Status.DEGENERATE).sum()),
            "bound_pixels": int(np.count_nonzero(r.bounds))}


def _against_truth(ds: xr.Dataset, scene: Scene, cube: SceneCube, r: PixelResults, truth: np.ndarray,
                   grid: CommonGrid, settings: AnalysisSettings) -> dict[str, Any]:
    """Calibration on the pure pixels, the parameter and error maps, and their metrics."""
    gsd_in = scene.spec.surface.gsd_m
    assert gsd_in is not None and settings.parameter is not None
    factor = round(grid.gsd_m / gsd_in)
    shape = grid.reflectance.shape[1:]
    t = truth_on_grid(truth, factor, shape).reshape(-1)
    pure = pure_pixels(cube.parcels, factor, shape).reshape(-1)
    regress = np.isin(r.status, settings.regress) & np.isfinite(r.index)
    calibrate = regress & pure & np.isfinite(t)
    name = settings.parameter
    out: dict[str, Any] = {"parameter": name, "calibration_pixels": int(calibrate.sum())}
    if calibrate.sum() < 3:
        out["note"] = "fewer than 3 pure pixels with a fit: no calibration, no parameter map"
        return out
    stats = regression_metrics(r.index[calibrate][None], r.status[calibrate][None], r.bounds[calibrate][None],
                               t[calibrate], regress=settings.regress)
    poly = poly2_fit(r.index[calibrate], np.ones(int(calibrate.sum()), bool), t[calibrate])
    estimate = np.where(regress, poly(np.where(regress, r.index, 0.0)), np.nan)
    error = estimate - t
    scored = np.isfinite(error)
    e, tt = error[scored], t[scored]
    ss_tot = float(((tt - tt.mean()) ** 2).sum()) if tt.size else 0.0
    out.update({f"calibration_{k}": np.asarray(v)[0].item() for k, v in stats.items()
                if k in ("rms", "r2", "robust_rms", "rms_unbounded", "n_valid")})
    out.update(calibration={"x0": poly.x0, "xs": poly.xs, "coef": list(poly.coef)},
               scored_pixels=int(scored.sum()),
               rms=float(np.sqrt(np.mean(e * e))) if e.size else float("nan"),
               bias=float(e.mean()) if e.size else float("nan"),
               r2=1.0 - float((e * e).sum()) / ss_tot if ss_tot > 0 else float("nan"))
    ny, nx = shape
    dims = grid.dims
    units = {"cab": "ug cm-2", "lai": "m2 m-2"}.get(name, "1")
    ds[f"{name}_map"] = (dims, estimate.reshape(ny, nx).astype(np.float32),
                         {"units": units, "long_name": f"{name} from the index, calibrated on the pure pixels"})
    ds[f"{name}_truth"] = (dims, t.reshape(ny, nx).astype(np.float32),
                           {"units": units, "long_name": f"true {name}, box mean (NaN where any part has none)"})
    ds[f"{name}_error"] = (dims, error.reshape(ny, nx).astype(np.float32),
                           {"units": units, "long_name": f"{name} map minus truth"})
    ds["pure_pixel"] = (dims, pure.reshape(ny, nx).astype(np.uint8),
                        {"long_name": "box inside one parcel (1) or across an edge (0)"})
    ds.attrs.update(analysis_parameter=name, analysis_calibration="second-order polynomial of the index fitted on "
                    "the pure pixels' truth (the regression of s2cl.retrieve.metrics)")
    out["map"] = f"{name}_map"
    return out
