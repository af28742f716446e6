"""``s2cl simulate`` of a library scene in bounded memory: chunks of whole spectra are sensed and
written straight into the NetCDF file, so memory does not grow with ``surface.copies``.

The file equals :meth:`LibrarySimulation.to_dataset` written with xarray (same variables, dimensions,
attributes and values; tested), written by the one writer of ``simulation.nc`` (:mod:`s2cl.io.simulation_file`,
the image cube's too): the small part (band and spectrum tables, noise-free band radiance) first; the per-pixel
images ``(band, y, x)`` are then created in the open file and filled chunk by chunk (``rows``: one image row per
spectrum; ``blocks``: one square tile per spectrum); clipping counts and the global attributes (the run's,
:func:`s2cl.forward.run_attrs.run_attrs`) last. The analysis keeps only the band reflectances
it needs (float32, ``n_analysis_bands × pixels``); its memory is part of :func:`simulate_memory`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from s2cl.app.analysis import analyse
from s2cl.cl.runtime import get_runtime
from s2cl.forward.sense import SenseResult

if TYPE_CHECKING:
    from s2cl.cl.runtime import Runtime
    from s2cl.scene.scene import Scene
from s2cl.app.chain_parts import checked_parts
from s2cl.app.checks import Checked
from s2cl.app.simulate_footprint import chunk_spectra, simulate_footprint
from s2cl.forward.dataset import PIXEL_SPECTRUM_ATTRS, PIXEL_VARIABLES, header_dataset, pixel_attrs
from s2cl.forward.resample import resample_buffers
from s2cl.forward.run_attrs import run_attrs
from s2cl.forward.sense import sense_buffers
from s2cl.forward.simulate import BandSummary, LibrarySimulation, Simulator
from s2cl.forward.stages import chain, outputs
from s2cl.io.budget import Budget, most_fitting, require_disk
from s2cl.io.simulation_file import simulation_file

Progress = Callable[[int], None]


@dataclass
class StreamedSimulation:
    """What ``s2cl simulate`` reports after streaming a library scene into ``path``."""

    path: Path
    rows: list[dict[str, Any]]
    attrs: dict[str, Any]
    pixels: int
    analysis: dict[str, Any] | None = None
    seconds: dict[str, float] = field(default_factory=dict)


def simulate_memory(checked: Checked, budget: Budget, *, device_memory: bool = True) -> float:
    """Peak memory (bytes) of :func:`simulate_to_netcdf` for ``checked``, from what it allocates
    (:func:`s2cl.app.simulate_footprint.simulate_footprint`; ``device_memory``: the device's buffers are the host's);
    :class:`ResourceError` naming ``surface.copies`` (with the most copies that fit, with an analysis, whose
    arrays grow with the copies) when it exceeds ``budget``."""
    scene, lib = checked.scene, checked.library
    assert lib is not None
    copies = scene.run.copies
    need = simulate_footprint(checked, device_memory=device_memory).peak
    analysis = checked.analysis is not None
    what = f"simulating {lib.size:,} spectra × {copies:,} copies" + (" with the analysis" if analysis else "")
    if need > budget.memory_bytes and analysis:
        most = _most_copies(checked, budget, device_memory)
        budget.require(need, what=what, key="surface.copies", source=scene.source,
                       fits=f"at most {most:,} copies fit (or remove [analysis])")
    budget.require(need, what=what, key="surface.copies", source=scene.source)
    return need


def _most_copies(checked: Checked, budget: Budget, device_memory: bool) -> int:
    """The most copies whose footprint fits ``budget`` (0: none), by bisection (a footprint grows with the copies,
    but for a chunk's rounding to whole spectra)."""
    def fits(c: int) -> bool:
        return simulate_footprint(checked, copies=c, device_memory=device_memory).peak <= budget.memory_bytes

    return most_fitting(fits, checked.scene.run.copies)


def require_device_launches(rt: Runtime, scene: Scene) -> None:
    """Refuse in one line, before any work, a device that cannot hold one spectrum of the resampling or one pixel of
    the per-pixel stages (:func:`s2cl.forward.resample.resample_buffers`, :func:`s2cl.forward.sense.sense_buffers`:
    the kernels' declarations; their launches are then sized to it). Row blocks of an image do not change what the
    device holds: their pixels go through these launches."""
    real_bytes = 8 if scene.run.precision == "float64" else 4
    nb, device = scene.sensor.size, rt.memory
    resampling = resample_buffers(nb, scene.grid.size, real_bytes, atmosphere=True)
    device.require(resampling, 1, what=f"resampling {scene.grid.size:,} wavelengths to {nb} bands",
                   key="grid.step_nm", source=scene.source, fits="coarsen the grid or choose a device with more "
                   "memory (compute.device, --device)")
    device.require(sense_buffers(chain(scene.effects), nb, real_bytes), 1, what=f"the per-pixel stages of {nb} bands",
                   key="compute.device", source=scene.source, fits="choose a device with more memory (--device)")


def netcdf_bytes(checked: Checked) -> float:
    """Size of ``simulation.nc`` (bytes, an upper bound) from the effects that are on."""
    scene, lib = checked.scene, checked.library
    assert lib is not None
    copies = scene.run.copies
    per_band = sum(o.itemsize("float32") for o in outputs(scene.effects))
    pixels = image_pixels(lib.size, copies, scene.run.layout)
    return 1.02 * pixels * (scene.sensor.size * per_band + 8) + 2e6


def require_netcdf_disk(checked: Checked, out: Path) -> None:
    """Refuse (one line, before any work) when ``simulation.nc`` would not fit on the disk of ``out``."""
    require_disk(out, netcdf_bytes(checked), what="simulation.nc", key="surface.copies",
                 source=checked.scene.source)


def image_shape(n_spectra: int, copies: int, layout: str) -> tuple[int, int, int]:
    """(rows, columns, tile side) of the image: see :func:`s2cl.forward.dataset.image_layout`."""
    if layout == "rows":
        return n_spectra, copies, 0
    side = math.isqrt(copies)
    ncols = math.ceil(math.sqrt(n_spectra))
    return math.ceil(n_spectra / ncols) * side, ncols * side, side


def image_pixels(n_spectra: int, copies: int, layout: str) -> int:
    rows, cols, _ = image_shape(n_spectra, copies, layout)
    return rows * cols


def simulate_to_netcdf(checked: Checked, path: Path, *, device: str | None = None,
                       progress: Progress | None = None) -> StreamedSimulation:
    """Simulate the checked library scene into NetCDF file ``path`` (written atomically); return the
    per-band summary, the attributes and the analysis (when the scene has one)."""
    scene, lib = checked.scene, checked.library
    assert lib is not None
    r = scene.run
    rt = get_runtime(device or r.device)
    parts = checked_parts(checked)
    sim = Simulator.of(rt, parts)
    t0 = time.perf_counter()
    band_radiance = sim.band_radiance(lib.spectra)
    seconds = {"resample": time.perf_counter() - t0}
    attrs = run_attrs(parts, rt.name, image=False)
    writer = _ImageWriter(scene, lib.size, r.copies)
    stats = BandSummary(scene.sensor, band_radiance, r.copies)
    picked = _AnalysisBands(checked, lib.size * r.copies)
    if progress:
        progress(0)
    flagged = "flags" in {o.name for o in outputs(scene.effects)}
    clipped = np.zeros((2, scene.sensor.size), np.int64) if flagged else None
    header = header_dataset(scene.sensor, lib, band_radiance, r.copies, r.layout, attrs, clipped, sim.stage_values())
    with simulation_file(path, header) as store:
        t1 = time.perf_counter()
        with writer.open(store.file) as images:
            _write_chunks(sim, band_radiance, checked, images, stats, picked, progress)
            if clipped is not None:
                images.set_clipped(stats.clipped)
        seconds["sense_and_write"] = time.perf_counter() - t1
    analysis = picked.analyse(band_radiance, rt) if checked.analysis is not None else None
    return StreamedSimulation(path, stats.rows(), attrs, lib.size * r.copies, analysis, seconds)


def _write_chunks(sim: Simulator, band_radiance: np.ndarray, checked: Checked, images: _OpenImages,
                  stats: BandSummary, picked: _AnalysisBands, progress: Progress | None) -> None:
    """Sense the library chunk by chunk into ``images``, ``stats`` and ``picked`` (a chunk's arrays are released
    when it is written: none is left for the analysis, :mod:`s2cl.app.simulate_footprint`)."""
    r, nb = checked.scene.run, checked.scene.sensor.size
    c = r.copies
    for lo, hi, out in _sensed_chunks(sim, band_radiance, c, r.seed, r.frame):
        parts = {name: None if getattr(out, name) is None else
                 getattr(out, name).reshape(nb, hi - lo, c) for name, _, _ in PIXEL_VARIABLES}
        images.write(lo, hi, parts)
        stats.add(lo, hi, parts["noisy"], parts["calibrated"], out.clipped, parts["flags"])
        picked.add(lo * c, out.reflectance)
        if progress:
            progress((hi - lo) * c)
        out = parts = None  # let the chunk go before the next is sensed (its footprint counts one chunk)


def _sensed_chunks(sim: Simulator, band_radiance: np.ndarray, copies: int, seed: int, frame: int):
    """(first spectrum, end spectrum, SenseResult) per chunk of whole spectra; pixel ``s · copies + c``
    keys the noise of copy ``c`` of spectrum ``s``, as in :meth:`Simulator.run_library`."""
    ns = band_radiance.shape[1]
    per_chunk = chunk_spectra(copies)
    for lo in range(0, ns, per_chunk):
        hi = min(ns, lo + per_chunk)
        expanded = np.repeat(band_radiance[:, lo:hi], copies, axis=1)
        out = sim.sense(expanded, seed=seed, frame=frame, pixel_offset=lo * copies)
        if out is None:  # no per-pixel stage: the images are the noise-free radiance
            out = SenseResult()
        yield lo, hi, out
        expanded = out = None  # the generator's own references, let go before the next chunk


class _ImageWriter:
    """Creates the per-pixel variables in an open NetCDF file and writes chunks of spectra into them."""

    def __init__(self, scene: Any, n_spectra: int, copies: int):
        self.layout = scene.run.layout
        self.n_spectra, self.copies, self.n_bands = n_spectra, copies, scene.sensor.size
        self.rows, self.cols, self.side = image_shape(n_spectra, copies, self.layout)
        self.effects = scene.effects
        self.dtype = np.dtype(scene.run.precision)

    def open(self, file: Any) -> _OpenImages:
        """The images created in ``file``, an open h5netcdf file (:func:`s2cl.io.simulation_file.simulation_file`)."""
        return _OpenImages(self, file)


class _OpenImages:
    def __init__(self, spec: _ImageWriter, file: Any):
        self.spec, self.file = spec, file

    def __enter__(self) -> _OpenImages:
        sp = self.spec
        self.file.dimensions["y"] = sp.rows
        self.file.dimensions["x"] = sp.cols
        v = self.file.create_variable("pixel_spectrum", ("y", "x"), np.int64)
        v.attrs.update(PIXEL_SPECTRUM_ATTRS)
        if sp.layout == "blocks":  # tiles beyond the last spectrum hold no pixel
            for s in range(sp.n_spectra, (sp.rows // sp.side) * (sp.cols // sp.side)):
                v[self._tile(s)] = -1
        self.vars = {"pixel_spectrum": v}
        on = {o.name: o for o in outputs(sp.effects)}
        for name, units, long_name in PIXEL_VARIABLES:
            if name not in on:
                continue
            dtype, fill = (on[name].dtype, None) if on[name].dtype is not None else (sp.dtype, np.nan)
            var = self.file.create_variable(name, ("band", "y", "x"), dtype, fillvalue=fill)
            var.attrs.update(pixel_attrs(name, units, long_name))
            self.vars[name] = var
        return self

    def __exit__(self, *exc: Any) -> None:
        """The file stays open: its writer closes it."""

    def write(self, lo: int, hi: int, parts: dict[str, np.ndarray | None]) -> None:
        """Spectra ``lo … hi-1``: each array ``(n_bands, hi - lo, copies)``."""
        sp = self.spec
        for name, part in parts.items():
            if part is None or name not in self.vars:
                continue
            if sp.layout == "rows":
                self.vars[name][:, lo:hi, :] = part
            else:
                for s in range(lo, hi):
                    self.vars[name][(slice(None), *self._tile(s))] = part[:, s - lo].reshape(-1, sp.side, sp.side)
        if sp.layout == "rows":
            self.vars["pixel_spectrum"][lo:hi, :] = np.broadcast_to(np.arange(lo, hi)[:, None], (hi - lo, sp.cols))
        else:
            for s in range(lo, hi):
                self.vars["pixel_spectrum"][self._tile(s)] = s

    def _tile(self, s: int) -> tuple[slice, slice]:
        sp = self.spec
        r, c = divmod(s, sp.cols // sp.side)
        return slice(r * sp.side, (r + 1) * sp.side), slice(c * sp.side, (c + 1) * sp.side)

    def set_clipped(self, clipped: np.ndarray | None) -> None:
        if clipped is not None:
            self.file.variables["clipped"][...] = clipped


class _AnalysisBands:
    """The corrected reflectance of the analysis bands, gathered chunk by chunk in the scene's precision."""

    def __init__(self, checked: Checked, n_pixels: int):
        self.checked = checked
        self.rows: list[int] = []
        self.data: np.ndarray | None = None
        if checked.analysis is not None:
            names = [b.lower() for b in checked.scene.sensor.band_names]
            self.rows = [names.index(b.lower()) for b in checked.analysis_bands]
            self.data = np.empty((len(self.rows), n_pixels), np.dtype(checked.scene.run.precision))

    def add(self, first_pixel: int, reflectance: np.ndarray | None) -> None:
        if self.data is not None and reflectance is not None:
            self.data[:, first_pixel : first_pixel + reflectance.shape[1]] = reflectance[self.rows]

    def analyse(self, band_radiance: np.ndarray, rt: Runtime) -> dict[str, Any]:
        scene, lib = self.checked.scene, self.checked.library
        assert self.data is not None and lib is not None
        sensor = scene.sensor.select(list(self.checked.analysis_bands))
        copies = scene.run.copies
        sim = LibrarySimulation(scene.name, sensor, lib, copies, scene.effects, band_radiance[self.rows],
                                outputs={"reflectance": self.data.reshape(len(self.rows), lib.size, copies)})
        return analyse(rt, scene, sim)
