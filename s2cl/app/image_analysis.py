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

from s2cl.app.analysis import retrieve_pixels
from s2cl.cl.runtime import Runtime
from s2cl.forward.cube import SceneCube
from s2cl.forward.row_blocks import box_mean
from s2cl.io.image_store import ImageStore
from s2cl.retrieve.analysis import AnalysisSettings
from s2cl.retrieve.metrics import fit_accounting, poly2_fit, regression_metrics
from s2cl.scene.scene import Scene
from s2cl.status import FITTED, Status

#: CF flag attributes of the analysis status (:class:`s2cl.status.Status`)
STATUS_ATTRS = {"long_name": "retrieval status per pixel",
                "flag_values": np.array([s.value for s in Status], np.uint8),
                "flag_meanings": " ".join(s.name.lower() for s in Status)}
#: the regression figures of the calibration on the pure pixels kept in the result (``calibration_<name>``)
CALIBRATION_FIGURES = ("rms", "r2", "robust_rms", "rms_unbounded", "n_valid")
GRID_RULE = "box average of each analysis band's reflectance to the coarsest analysis band's GSD"


@dataclass(frozen=True)
class CommonGrid:
    """The analysis bands on one grid of ``gsd_m``: ``(ny, nx)`` pixels, each band ``factors[k]`` of its own pixels
    a side."""

    bands: list[str]
    factors: list[int]
    gsd_m: float
    ny: int
    nx: int

    @property
    def dims(self) -> tuple[str, str]:
        return f"y_{self.gsd_m:g}m", f"x_{self.gsd_m:g}m"

    @classmethod
    def of(cls, store: ImageStore, scene: Scene, bands: list[str]) -> CommonGrid:
        shapes = [scene.sensor.band(b) for b in bands]
        gsd = max(b.gsd_m for b in shapes)
        factors = [round(gsd / b.gsd_m) for b in shapes]
        sizes = [store.shape(f"reflectance_{b.name}") for b in shapes]
        return cls([b.name for b in shapes], factors, gsd, min(s[0] // f for s, f in zip(sizes, factors, strict=True)),
                   min(s[1] // f for s, f in zip(sizes, factors, strict=True)))

    def reflectance(self, store: ImageStore, rows: slice) -> np.ndarray:
        """The bands' corrected reflectance ``(n_bands, n_rows, nx)`` of common-grid ``rows``, box-averaged."""
        return np.stack([box_mean(store.read(f"reflectance_{b}", slice(rows.start * f, rows.stop * f)), f)[:, : self.nx]
                         for b, f in zip(self.bands, self.factors, strict=True)])

    def flags(self, store: ImageStore, rows: slice) -> np.ndarray | None:
        """The OR of the bands' radiometric flags in each box of ``rows`` (None when the chain writes no flags)."""
        out = None
        for b, f in zip(self.bands, self.factors, strict=True):
            if f"flags_{b}" in store:
                x = _box_or(store.read(f"flags_{b}", slice(rows.start * f, rows.stop * f)), f)[:, : self.nx]
                out = x if out is None else out | x
        return out


def common_grid(store: ImageStore, scene: Scene, bands: list[str]) -> np.ndarray:
    """The analysis ``bands``' corrected reflectance box-averaged to the coarsest band's GSD ``(n_bands, ny, nx)``."""
    g = CommonGrid.of(store, scene, bands)
    return g.reflectance(store, slice(0, g.ny))


def _box_or(flags: np.ndarray, factor: int) -> np.ndarray:
    """Bitwise OR of ``factor × factor`` blocks (trailing partial blocks dropped, as :func:`box_mean` does)."""
    if factor == 1:
        return flags
    rows, cols = (flags.shape[0] // factor) * factor, (flags.shape[1] // factor) * factor
    blocks = flags[:rows, :cols].reshape(rows // factor, factor, cols // factor, factor)
    return np.bitwise_or.reduce(np.bitwise_or.reduce(blocks, axis=3), axis=1)


def truth_on_grid(truth: np.ndarray, factor: int, nx: int) -> np.ndarray:
    """A truth map at the input GSD box-averaged by ``factor`` (NaN where any input pixel of the box has none)."""
    return box_mean(np.asarray(truth, dtype=np.float64), factor)[:, :nx]


def pure_pixels(parcels: np.ndarray, factor: int, nx: int) -> np.ndarray:
    """Pixels whose ``factor × factor`` box of ``parcels`` lies inside one parcel."""
    p = np.asarray(parcels, dtype=np.float64)
    if factor == 1:
        return np.ones((p.shape[0], nx), bool)
    rows, cols = (p.shape[0] // factor) * factor, (p.shape[1] // factor) * factor
    blocks = p[:rows, :cols].reshape(rows // factor, factor, cols // factor, factor)
    return (blocks.min(axis=(1, 3)) == blocks.max(axis=(1, 3)))[:, :nx]


def analyse_image(rt: Runtime, scene: Scene, store: ImageStore, cube: SceneCube, bands: list[str],
                  settings: AnalysisSettings, *, block_rows: int | None = None) -> dict[str, Any]:
    """Run the scene's analysis on the image already in ``store`` (:func:`s2cl.forward.cube.simulate_cube`),
    ``block_rows`` rows of the common grid at a time (default: all), reading the analysis bands' reflectance back; add
    its map, status, flags (and, with a truth, the parameter, truth and error maps) to ``store``; return the metrics
    and the fit accounting (``simulation.json``'s analysis). ``s2cl simulate`` reads nothing back: it feeds the
    analysis as it writes (:class:`StreamedAnalysis`)."""
    grid = CommonGrid.of(store, scene, bands)
    step = block_rows or grid.ny
    retrieval = _Retrieval(rt, scene, grid, bands, settings)
    flagged = any(f"flags_{b}" in store for b in grid.bands)
    for r0 in range(0, grid.ny, step):
        rows = slice(r0, min(grid.ny, r0 + step))
        retrieval.add(rows, grid.reflectance(store, rows), grid.flags(store, rows) if flagged else None)
    return retrieval.finish(store, cube, step)


class StreamedAnalysis:
    """The scene's analysis fed by the simulation as it writes (``s2cl simulate``): :meth:`tee` wraps the store the
    simulation writes into, and the analysis bands' reflectance and flags rows are kept as they are written, until
    every band holds whole rows of the common grid, which are retrieved then and let go; nothing is read back from the
    file. The rows held are at most a block's (the footprint counts them with the block,
    :meth:`s2cl.app.cube_footprint.CubeFootprint.block`); the map, status, bounds and flags are held whole, as the
    footprint counts them (:func:`s2cl.app.cube_footprint.cube_footprint`), and written when it finishes."""

    def __init__(self, rt: Runtime, scene: Scene, bands: list[str], settings: AnalysisSettings, rows: int,
                 cols: int):
        shapes = [scene.sensor.band(b) for b in bands]
        gsd, gsd_in = max(b.gsd_m for b in shapes), scene.spec.surface.gsd_m or 1.0
        factors = [round(gsd / b.gsd_m) for b in shapes]
        sizes = [(rows // round(b.gsd_m / gsd_in), cols // round(b.gsd_m / gsd_in)) for b in shapes]
        self.grid = CommonGrid([b.name for b in shapes], factors, gsd,
                               min(s[0] // f for s, f in zip(sizes, factors, strict=True)),
                               min(s[1] // f for s, f in zip(sizes, factors, strict=True)))
        self.retrieval = _Retrieval(rt, scene, self.grid, bands, settings)
        self._held: dict[str, list[np.ndarray]] = {f"{k}_{b}": [] for b in self.grid.bands for k in ("reflectance",
                                                                                                     "flags")}
        self._received = dict.fromkeys(self._held, 0)
        self._done = 0

    def tee(self, store: ImageStore) -> ImageStore:
        """``store``, each row block written into it also handed to this analysis."""
        return _Tee(store, self)  # type: ignore[return-value]

    def written(self, name: str, rows: slice, data: np.ndarray) -> None:
        """Rows ``rows`` of variable ``name`` were written: keep an analysis band's, and retrieve the common grid's
        rows that every band now holds whole."""
        if name not in self._held:
            return
        assert rows.start == self._received[name], f"{name}: rows out of order"
        self._held[name].append(data)
        self._received[name] = rows.stop
        g = self.grid
        ready = min(g.ny, *(self._received[f"reflectance_{b}"] // f for b, f in zip(g.bands, g.factors, strict=True)))
        if ready <= self._done:
            return
        rows_now, refl, flags = slice(self._done, ready), [], None
        for b, f in zip(g.bands, g.factors, strict=True):
            refl.append(box_mean(self._take(f"reflectance_{b}", (ready - self._done) * f), f)[:, : g.nx])
            if self._received[f"flags_{b}"]:
                x = _box_or(self._take(f"flags_{b}", (ready - self._done) * f), f)[:, : g.nx]
                flags = x if flags is None else flags | x
        self.retrieval.add(rows_now, np.stack(refl), flags)
        self._done = ready

    def _take(self, name: str, n: int) -> np.ndarray:
        """The first ``n`` rows held of ``name``, let go."""
        held = self._held[name]
        data = held[0] if len(held) == 1 else np.concatenate(held)
        self._held[name] = [data[n:]] if data.shape[0] > n else []
        return data[:n]

    def finish(self, store: ImageStore, cube: SceneCube, step: int | None) -> dict[str, Any]:
        """Write the analysis into ``store`` (:func:`analyse_image`'s variables and attributes) and return its
        figures; ``step``: common-grid rows the truth maps are made at a time (default: all)."""
        assert self._done == self.grid.ny, "the simulation did not write every row"
        return self.retrieval.finish(store, cube, step or self.grid.ny)


class _Tee:
    """An image store whose writes are also handed to a :class:`StreamedAnalysis`."""

    def __init__(self, store: ImageStore, analysis: StreamedAnalysis):
        self._store, self._analysis = store, analysis

    def __getattr__(self, name: str) -> Any:
        return getattr(self._store, name)

    def __contains__(self, name: str) -> bool:
        return name in self._store

    def write(self, name: str, rows: slice, data: np.ndarray) -> None:
        self._store.write(name, rows, data)
        self._analysis.written(name, rows, data)


class _Retrieval:
    """The analysis's per-pixel results on the common grid, retrieved a band of rows at a time, written into the
    store once all are in."""

    def __init__(self, rt: Runtime, scene: Scene, grid: CommonGrid, bands: list[str], settings: AnalysisSettings):
        self.rt, self.scene, self.grid, self.bands, self.settings = rt, scene, grid, bands, settings
        self.index = np.empty((grid.ny, grid.nx), np.float32)
        self.status = np.empty((grid.ny, grid.nx), np.uint8)
        self.bounds = np.empty((grid.ny, grid.nx), np.uint8)
        self.flags: np.ndarray | None = None

    def add(self, rows: slice, refl: np.ndarray, flags: np.ndarray | None) -> None:
        """Common-grid ``rows``: the bands' reflectance ``(n_bands, n_rows, nx)`` and the OR of their flags (None:
        the chain writes none)."""
        r = retrieve_pixels(self.rt, self.scene, self.bands, self.settings, refl.reshape(refl.shape[0], -1))
        shape = refl.shape[1:]
        self.index[rows], self.status[rows], self.bounds[rows] = (r.index.reshape(shape), r.status.reshape(shape),
                                                                  r.bounds.reshape(shape))
        if flags is not None:
            if self.flags is None:
                self.flags = np.zeros((self.grid.ny, self.grid.nx), np.uint8)
            self.flags[rows] = flags

    def finish(self, store: ImageStore, cube: SceneCube, step: int) -> dict[str, Any]:
        grid, settings, bands = self.grid, self.settings, self.bands
        dims = grid.dims
        store.create("analysis_index", dims, np.float32,
                     {"long_name": f"{settings.kind} retrieval on {' '.join(bands)} (igrm: inflection wavelength lp "
                      "in nm; an index or formula: its value)", "analysis_kind": settings.kind})
        store.create("analysis_status", dims, np.uint8, dict(STATUS_ATTRS))
        store.create("analysis_bounds", dims, np.uint8, {"long_name": "fit on a parameter bound (IGRM), 0: no"})
        if self.flags is not None:
            store.create("analysis_flags", dims, np.uint8, {**_flag_attrs(store), "long_name": "OR of the "
                                                             "radiometric flags of the analysis bands' pixels in each "
                                                             "box"})
        everything = slice(0, grid.ny)
        for name, arr in (("analysis_index", self.index), ("analysis_status", self.status),
                          ("analysis_bounds", self.bounds), ("analysis_flags", self.flags)):
            if arr is not None:
                store.write(name, everything, arr)
        store.attrs.update(analysis_kind=settings.kind, analysis_bands=" ".join(bands), analysis_gsd_m=grid.gsd_m,
                           analysis_grid=GRID_RULE)
        out: dict[str, Any] = {"kind": settings.kind, "bands": bands, "map": "analysis_index", "gsd_m": grid.gsd_m,
                               "grid": GRID_RULE, "pixels": int(grid.ny * grid.nx),
                               **_accounting(self.status.reshape(-1), self.bounds.reshape(-1))}
        if cube.knows(settings.parameter or "") and cube.parcels is not None:
            fit = (self.index, self.status, self.bounds)
            out.update(_against_truth(store, self.scene, cube, fit, grid, settings, step))
        return out


def _flag_attrs(store: ImageStore) -> dict[str, Any]:
    names = [n for n in store.names() if str(n).startswith("flags_")]
    a = store.attrs_of(names[0]) if names else {}
    return {k: a[k] for k in ("flag_masks", "flag_meanings") if k in a}


def _accounting(status: np.ndarray, bounds: np.ndarray) -> dict[str, Any]:
    """How many pixels were fitted, invalid, degenerate, on a bound; the fractions per status."""
    acc = {k: float(v[0]) for k, v in fit_accounting(status[None], bounds[None]).items()}
    return {**acc, "fitted_pixels": int(np.isin(status, FITTED).sum()),
            "invalid_pixels": int((status == Status.INVALID).sum()),
            "degenerate_pixels": int((status == Status.DEGENERATE).sum()),
            "bound_pixels": int(np.count_nonzero(bounds))}


def _against_truth(store: ImageStore, scene: Scene, cube: SceneCube, fit: tuple[np.ndarray, ...], grid: CommonGrid,
                   settings: AnalysisSettings, step: int) -> dict[str, Any]:
    """Calibration on the pure pixels, the parameter, truth and error maps (written ``step`` rows at a time), and
    their metrics; ``fit``: the map's index, status and bounds."""
    index, status, bounds = fit
    gsd_in = scene.spec.surface.gsd_m
    assert gsd_in is not None and settings.parameter is not None and cube.parcels is not None
    name, f = settings.parameter, round(grid.gsd_m / gsd_in)
    regress = np.isin(status, settings.regress) & np.isfinite(index)
    xs, ts, bs = [], [], []
    for r0 in range(0, grid.ny, step):
        rows = slice(r0, min(grid.ny, r0 + step))
        t = truth_on_grid(cube.truth(name, slice(rows.start * f, rows.stop * f)), f, grid.nx)
        use = regress[rows] & pure_pixels(cube.parcels[rows.start * f : rows.stop * f], f, grid.nx) & np.isfinite(t)
        xs.append(index[rows][use].astype(np.float64))
        ts.append(t[use])
        bs.append(bounds[rows][use])
    x, t_cal = np.concatenate(xs), np.concatenate(ts)
    out: dict[str, Any] = {"parameter": name, "calibration_pixels": int(x.size)}
    if x.size < 3:
        out["note"] = "fewer than 3 pure pixels with a fit: no calibration, no parameter map"
        return out
    n = x.size
    stats = regression_metrics(x[None], np.zeros((1, n), np.uint8), np.concatenate(bs)[None], t_cal,
                               regress=(int(Status.OK),))  # x holds the pixels that enter the regression
    poly = poly2_fit(x, np.ones(n, bool), t_cal)
    out.update({f"calibration_{k}": np.asarray(v)[0].item() for k, v in stats.items()
                if k in CALIBRATION_FIGURES})
    out["calibration"] = {"x0": poly.x0, "xs": poly.xs, "coef": list(poly.coef)}
    units = {"cab": "ug cm-2", "lai": "m2 m-2"}.get(name, "1")
    for var, long_name in ((f"{name}_map", f"{name} from the index, calibrated on the pure pixels"),
                           (f"{name}_truth", f"true {name}, box mean (NaN where any part has none)"),
                           (f"{name}_error", f"{name} map minus truth")):
        store.create(var, grid.dims, np.float32, {"units": units, "long_name": long_name})
    store.create("pure_pixel", grid.dims, np.uint8, {"long_name": "box inside one parcel (1) or across an edge (0)"})
    sums = np.zeros(5)  # n, Σe, Σe², Σt, Σt² over the scored pixels
    for r0 in range(0, grid.ny, step):
        rows = slice(r0, min(grid.ny, r0 + step))
        fine = slice(rows.start * f, rows.stop * f)
        t = truth_on_grid(cube.truth(name, fine), f, grid.nx)
        estimate = np.where(regress[rows], poly(np.where(regress[rows], index[rows], 0.0)), np.nan)
        error = estimate - t
        scored = np.isfinite(error)
        e, tt = error[scored], t[scored]
        sums += (e.size, e.sum(), (e * e).sum(), tt.sum(), (tt * tt).sum())
        for var, arr in ((f"{name}_map", estimate), (f"{name}_truth", t), (f"{name}_error", error)):
            store.write(var, rows, arr.astype(np.float32))
        store.write("pure_pixel", rows, pure_pixels(cube.parcels[fine], f, grid.nx).astype(np.uint8))
    count, se, se2, st, st2 = sums
    ss_tot = st2 - st * st / count if count else 0.0
    out.update(scored_pixels=int(count), rms=float(np.sqrt(se2 / count)) if count else float("nan"),
               bias=float(se / count) if count else float("nan"),
               r2=1.0 - float(se2) / ss_tot if ss_tot > 0 else float("nan"))
    store.attrs.update(analysis_parameter=name, analysis_calibration="second-order polynomial of the index fitted "
                       "on the pure pixels' truth (the regression of s2cl.retrieve.metrics)")
    out["map"] = f"{name}_map"
    return out
