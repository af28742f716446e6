"""``s2cl simulate`` as a function: a scene checked, then streamed through the sensor chain into
``simulation.nc`` and ``simulation.json`` (an image cube by blocks of rows); what the command prints, as data."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from s2cl.app.chain_parts import checked_parts, scene_instrument
from s2cl.app.checks import Checked, check_simulate
from s2cl.app.image_analysis import StreamedAnalysis
from s2cl.app.image_quicklook import write_quicklook
from s2cl.app.optimise import output_folder
from s2cl.app.simulate import require_device_launches, require_netcdf_disk, simulate_memory, simulate_to_netcdf
from s2cl.cl.runtime import get_runtime
from s2cl.errors import InputError, errors_in
from s2cl.forward.cube import open_scene_cube, simulate_cube
from s2cl.forward.reach import band_groups, cube_halo
from s2cl.io.budget import BASELINE_BYTES, Budget
from s2cl.io.cog import write_cogs
from s2cl.io.outdir import check_output_dir, claim
from s2cl.io.output import require_free, write_json
from s2cl.io.products.geotiff import rasterio_module
from s2cl.io.simulation_file import SIMULATION_NC, simulation_file
from s2cl.scene.caveats import report
from s2cl.scene.scene import Scene

SIMULATION_JSON = "simulation.json"

#: bytes per pixel of a block of a cube: per input wavelength (as stored, and float64 as read), per grid
#: wavelength (on the grid, TOA radiance, resampling input) and per band (images, noise, DN, calibration)
CUBE_BYTES_PER_INPUT, CUBE_BYTES_PER_GRID, CUBE_BYTES_PER_BAND = 16, 24, 48
#: bytes per input pixel of a generated cube held whole: labels, parcel ids, the map's index, status and bounds
CUBE_BYTES_GENERATED = 16
#: bytes per input pixel of a cube file held whole: the map's index, status and bounds (its NODATA mask and the
#: bands' footprint masks, once held whole, are now found block by block as its rows are read)
CUBE_BYTES_FILE = 16
#: bytes on disk per input pixel and band at most (radiance float64 with a PSF, noisy, calibrated and reflectance
#: float32, DN, flags)
CUBE_DISK_BYTES_PER_BAND = 23
#: bytes on disk per input pixel and band of a COG at most (float32 radiance, uncompressed)
COG_BYTES_PER_BAND = 4


@dataclass(frozen=True)
class SimulationRun:
    """A finished ``simulate``: the files ``written``; for a library scene also the per-band summary ``rows``,
    the NetCDF attributes ``attrs``, the scene's ``analysis`` (or None), ``pixels`` and ``seconds``."""

    scene: str
    folder: Path
    written: tuple[Path, ...]
    rows: list[dict[str, Any]] = field(default_factory=list)
    attrs: dict[str, Any] = field(default_factory=dict)
    analysis: dict[str, Any] | None = None
    pixels: int = 0
    seconds: float = 0.0


def simulate_scene(scene: str | Path | Scene = "default", out: str | Path | None = None, *,
                   device: str | None = None, max_memory: str | None = None,
                   progress: Callable[[int], None] | None = None,
                   on_start: Callable[[str, int], None] | None = None, fmt: str | None = None) -> SimulationRun:
    """Check ``scene`` (memory, disk, device and output folder included) before anything is created, then simulate
    it into ``out`` (default: the scene's output folder). ``on_start(label, total)`` is called once before the
    pixels stream, ``progress(n)`` as they do. ``fmt``: ``netcdf`` or ``cog`` (also Cloud-Optimised GeoTIFFs of an
    image, :mod:`s2cl.io.cog`); default the scene's ``output.format``."""
    budget = Budget.of(max_memory)
    sc = scene if isinstance(scene, Scene) else Scene.load(str(scene))
    folder, where = output_folder(sc, out)
    cog = _cog_format(sc, fmt)
    checked = check_simulate(sc, budget=budget)  # a cube file's metadata opened once: the scene completed from it
    sc = checked.scene
    check_output_dir(folder, where=where)
    if checked.cube is not None:
        return _simulate_cube(checked, folder, device, budget, progress, on_start, cog)
    # a device that does not exist, or cannot hold one launch, is refused before the folder is made; its buffers are
    # the host's memory where it works in it (PoCL's CPU devices)
    rt = get_runtime(device or sc.run.device)
    simulate_memory(checked, budget, device_memory=rt.host_memory)
    require_netcdf_disk(checked, folder)
    require_device_launches(rt, sc)
    warnings = report(checked.caveats)
    total = checked.library.size * sc.run.copies
    t0 = time.perf_counter()
    with claim(folder):
        if on_start:
            on_start(f"{sc.name}: {checked.library.size} spectra × {sc.run.copies}", total)
        result = simulate_to_netcdf(checked, folder / SIMULATION_NC, device=device, progress=progress)
        seconds = time.perf_counter() - t0
        write_json(folder / SIMULATION_JSON, {"scene": sc.name, "attrs": result.attrs, "pixels": total,
                                              "seconds": seconds, "stage_seconds": result.seconds,
                                              "bands": result.rows, "analysis": result.analysis,
                                              "warnings": warnings})
    return SimulationRun(sc.name, folder, (folder / SIMULATION_NC, folder / SIMULATION_JSON), result.rows,
                         result.attrs, result.analysis, total, seconds)


def _cog_format(sc: Scene, fmt: str | None) -> bool:
    """Whether the run writes COGs (``fmt``, else ``output.format``), checked: an image scene, the geo extra."""
    fmt = fmt or sc.spec.output.format
    if fmt not in ("netcdf", "cog"):
        raise InputError(f"must be 'netcdf' or 'cog', got {fmt!r}", key="--format")
    if fmt != "cog":
        return False
    if sc.spec.surface.cube is None:
        raise InputError("'cog' writes GeoTIFFs of an image; a library scene has none (simulation.nc holds its "
                         "pixels)", source=sc.source, key="output.format")

    rasterio_module()  # the geo extra, before anything is created
    return True


def cube_block_rows(sc: Scene, budget: Any, rows: int, cols: int, wavelengths: int = 0,
                    interpolated: bool = False) -> int | None:
    """Input rows of the scene's ``rows × cols`` cube (``wavelengths`` per pixel in its file; 0: generated)
    simulated at a time within ``budget`` (None: the whole image fits); a :class:`ResourceError` naming
    ``surface.cube`` when not even one block of rows fits. ``interpolated``: the resampling kernel puts the file's
    own bands on the grid (:attr:`s2cl.forward.parts.ResolvedCube.interpolates`), so no spectra on the grid are held.

    What does not stream (:func:`cube_whole_bytes`): a generated cube's labels and parcel ids, and the map's index,
    status and bounds (a cube file's NODATA mask streams: each block's own, found as it is read). What does: per
    band and input pixel of a block and of the rows it is read with on each side (the halo of its spatial filters,
    [spatial] PSF and [instrument] MTF and shift: :func:`s2cl.forward.reach.cube_halo`, the block reader's own), the
    band images, the radiometric stage's outputs and the analysis (:data:`CUBE_BYTES_PER_BAND`), and a file's
    spectra, read by rows (:data:`CUBE_BYTES_PER_INPUT`) and, unless ``interpolated``, put on the grid
    (:data:`CUBE_BYTES_PER_GRID`) on their way through the resampler."""
    grid = 0 if interpolated else CUBE_BYTES_PER_GRID * sc.grid.size
    spectra = CUBE_BYTES_PER_INPUT * wavelengths + grid if wavelengths else 0
    per_row = cols * (CUBE_BYTES_PER_BAND * sc.sensor.size + spectra)
    with errors_in(sc.source):
        groups = band_groups(sc.sensor, sc.spec.surface.gsd_m)
        halo = cube_halo(scene_instrument(sc), groups)
    factors = [factor for factor, _ in groups]
    unit = math.lcm(*factors)
    fixed = BASELINE_BYTES + cube_whole_bytes(sc, rows * cols, wavelengths)
    if fixed + (rows + 2 * halo) * per_row <= budget.memory_bytes:
        return None
    budget.require(fixed + (unit + 2 * halo) * per_row, what=f"a cube of {rows * cols:,} pixels × {wavelengths} "
                   f"wavelengths in blocks of {unit} rows", key="surface.cube", source=sc.source,
                   fits="crop the cube or coarsen grid.step_nm")
    return max(unit, int((budget.memory_bytes - fixed) // per_row) - 2 * halo)


def cube_whole_bytes(sc: Scene, pixels: int, wavelengths: int) -> float:
    """Bytes a cube holds whole whatever the blocks: a file's :data:`CUBE_BYTES_FILE` per pixel, or a generated
    cube's :data:`CUBE_BYTES_GENERATED`."""
    return pixels * (CUBE_BYTES_FILE if wavelengths else CUBE_BYTES_GENERATED)


def _simulate_cube(checked: Checked, folder: Path, device: str | None, budget: Any,
                   progress: Callable[[int], None] | None,
                   on_start: Callable[[str, int], None] | None, cog: bool = False) -> SimulationRun:
    """Simulate the scene's image cube (sized from its metadata, checked before the folder is made) into
    ``simulation.nc``, row block by row block within ``budget`` (:func:`cube_block_rows`), and ``simulation.json``;
    with an [analysis], its map goes into ``simulation.nc`` and a quicklook into ``quicklook.png``
    (:mod:`s2cl.app.image_analysis`); with ``cog``, the GSD groups and the maps as COGs (:mod:`s2cl.io.cog`)."""
    sc, resolved = checked.scene, checked.cube
    assert resolved is not None
    pixels, wavelengths = resolved.pixels, resolved.wavelengths  # from the metadata the checks opened
    budget.require(BASELINE_BYTES + cube_whole_bytes(sc, pixels, wavelengths), what=f"a cube of {pixels:,} pixels "
                   f"× {wavelengths} wavelengths", key="surface.cube", source=sc.source,
                   fits="crop the cube or coarsen grid.step_nm")  # a cube's whole part must fit before it is read
    # and one block of rows must fit before it is read
    block_rows = cube_block_rows(sc, budget, resolved.rows, resolved.cols, wavelengths, resolved.interpolates)
    rt = get_runtime(device or sc.run.device)
    require_device_launches(rt, sc)
    with errors_in(sc.source):
        parts = checked_parts(checked)
        cube = open_scene_cube(resolved, parts)
        groups = band_groups(sc.sensor, resolved.gsd_m)
    per_band = CUBE_DISK_BYTES_PER_BAND + (2 * COG_BYTES_PER_BAND if cog else 0)  # a COG and its strips, at once
    require_free(folder / SIMULATION_NC, 1.02 * cube.rows * cube.cols * per_band * sc.sensor.size + 2e6)
    warnings = report(checked.caveats)
    t0 = time.perf_counter()
    nc = folder / SIMULATION_NC
    written = [nc, folder / SIMULATION_JSON]
    with claim(folder):
        if on_start:
            on_start(f"{sc.name}: cube", cube.rows * cube.cols)
        with simulation_file(nc) as store:
            streamed = None  # the analysis is fed the rows as they are written: nothing is read back
            if checked.analysis is not None:
                streamed = StreamedAnalysis(rt, sc, list(checked.analysis_bands), checked.analysis, cube.rows,
                                            cube.cols)
            with errors_in(sc.source):
                simulate_cube(rt, parts, cube, progress=progress, store=store if streamed is None else
                              streamed.tee(store), block_rows=block_rows)
            analysis = None
            if streamed is not None:
                analysis = streamed.finish(store, cube, _analysis_step(checked, block_rows))
                written.append(folder / "quicklook.png")
                write_quicklook(store, written[-1], analysis["map"])
            if cog:
                written += write_cogs(store, folder, sc, cube.georef, analysis, groups)
            attrs = {k: (v.item() if hasattr(v, "item") else v) for k, v in store.attrs.items()}
        seconds = time.perf_counter() - t0
        write_json(folder / SIMULATION_JSON, {"scene": sc.name, "attrs": attrs, "pixels": cube.rows * cube.cols,
                                              "block_rows": block_rows, "seconds": seconds, "analysis": analysis,
                                              "warnings": warnings})
    return SimulationRun(sc.name, folder, tuple(written), attrs=attrs, analysis=analysis,
                         pixels=cube.rows * cube.cols, seconds=seconds)


def _analysis_step(checked: Checked, block_rows: int | None) -> int | None:
    """Rows of the analysis's common grid in as many input rows as a block of the simulation (None: all)."""
    sc, bands = checked.scene, list(checked.analysis_bands)
    factor = max(sc.sensor.band(b).gsd_m for b in bands) / (sc.spec.surface.gsd_m or 1.0)
    return None if block_rows is None else max(1, int(block_rows // factor))
